"""The clock in its environment: barometric and thermal coefficients from
steady states, and a year of weather.

Every coefficient is a central difference of steady-state rates: the
periodic orbit is found by shooting (clockwork.engine.shooting) at the
scene's conditions moved by -delta and +delta, on the same instances. The
rate is T0/T - 1 in s/day, positive when the clock gains (the sign of the
horologists' coefficients: the Trinity clock's -8.6 ms/day per mbar is a
loss when the pressure rises).

``barometric_coefficient``: the Air component's pressure moves; beside the
total, the part that buoyancy and added mass alone would give at the
amplitude held fixed (clockwork.physics.air.period_factor with the Air
FMU's densities), and the rest, which the change of amplitude brings (the
air's drag on the arc: circular and escapement errors).
``thermal_coefficient``: the temperature moves for the rod (the Pendulum's
temperature input), for the air (the Air's), and for both.
``weather_year``: the clock's accumulated error over a year of weather
(clockwork.physics.air.weather_year) at the scene's arc and at the
compensating arc (where the barometric coefficient is zero, found by a
secant search on the escapement's torque). The amplitude settles in Q/pi
periods, minutes, while the weather moves over hours and days, so the rate
follows the steady state of the moment: the stationary solution of the
averaged (Hoyng) equations, taken from shooting on a grid of pressures and
temperatures and fitted by a quadratic. A full co-simulation over the
first ``check_days`` tests that: the same hourly weather, the clock's
ticks counted against the regulated period.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ..engine.shooting import Shooter
from ..errors import SimulationError
from ..physics import air as airphys
from ..physics import analytic
from ..scene.kinds import Invalid
from . import keys
from .bounds import MAX_STEPS
from .context import ESCAPEMENTS, build_system, find_component, master_settings, parameters
from .registry import register
from .steady_state import AMPLITUDE_GUESS, MAX_PERIODS, TOLERANCE, Clock, SteadyState, clock_at, clock_check, \
    find_steady_state

DAY = analytic.SECONDS_PER_DAY
HPA = airphys.PA_PER_HPA

_COMMON = {"tolerance_s_per_day": TOLERANCE, "max_periods": MAX_PERIODS, "amplitude_guess": AMPLITUDE_GUESS}

# Moves of the Air's conditions: positive, bounded by what the Air FMU takes
# (checked at each point by _check_*: the scene's pressure and temperature
# moved by the key must stay inside the FMUs' declared ranges).
_IN_AIR_P = "the Air's pressure ± it within the Air FMU's pressure range"
_IN_AIR_T = "the Air's (and the Pendulum's) temperature ± it within their FMUs' temperature ranges"
DELTA_HPA = keys.number(0, 1000, lo_open=True, unit="hPa", also=_IN_AIR_P)
DELTA_K = keys.number(0, 100, lo_open=True, unit="K", also=_IN_AIR_T)
GRID_HPA = keys.number(0, 1000, lo_open=True, unit="hPa", also=_IN_AIR_P)
GRID_K = keys.number(0, 100, lo_open=True, unit="K", also=_IN_AIR_T)
# The weather's excursions: the year's pressures and temperatures must lie
# on the grid the rates are fitted on (p0 +- grid_hPa, T0 +- grid_K) with
# half of it to spare (the quadratic beyond its nodes), and in the FMUs' ranges.
WEATHER_SPARE = 1.5
_ON_GRID_P = f"the year's pressures within {WEATHER_SPARE:g} grid_hPa of the Air's and in the Air FMU's range"
_ON_GRID_T = (f"the year's temperatures within {WEATHER_SPARE:g} grid_K of the Air's and in the Air's and the "
              "Pendulum's ranges")


def _air(scene, analysis: str) -> str:
    air = find_component(scene, "Air")
    if air is None:
        raise SimulationError(f"the {analysis} analysis needs an Air component")
    return air


class Stalled(Exception):
    """A steady state the coefficient needs is a stall (a result, not an error)."""

    def __init__(self, state: SteadyState):
        super().__init__(state.reason)
        self.state = state


class _Rates:
    """Steady states of one clock under moved conditions, on one system."""

    def __init__(self, scene, clock: Clock, system, air: str):
        cfg = scene.analysis or {}
        self.clock, self.system, self.air = clock, system, air
        self.shooter = Shooter(system.master, clock.params, clock.pendulum, clock.params[clock.pendulum],
                               max_period_factor=float(cfg.get("max_periods", 3)))
        self.guess = clock.guess
        self.base: dict[tuple[str, str], float] = {}  # changes every steady state gets

    def parameters(self, changes: dict[tuple[str, str], float]) -> dict[str, dict]:
        params = {k: dict(v) for k, v in self.clock.params.items()}
        for (inst, name), value in {**self.base, **changes}.items():
            params[inst][name] = value
        return params

    def at(self, changes: dict[tuple[str, str], float]) -> tuple[SteadyState, float, float]:
        """The steady state with these (instance, variable) values, and the
        Air's density and viscosity there."""
        params = self.parameters(changes)
        self.shooter.parameters = params
        ss = find_steady_state(self.shooter, self.guess, self.clock.min_amplitude, tolerance=self.clock.tolerance)
        if ss.stalled:
            raise Stalled(ss)
        self.guess = ss.amplitude
        return ss, self.system.value(self.air, "density"), self.system.value(self.air, "viscosity")

    def statistics(self) -> dict:
        return vars(self.system.master.stats).copy()


def rate(ss: SteadyState) -> float:
    """1 - T/T0 = -E_T in s/day, positive: the clock gains."""
    return -ss.E_T * DAY


def _system(scene, point, clock: Clock, air: str):
    return build_system(scene, point, record={clock.pendulum: ["tick_time", "tick_w", "amplitude"],
                                              air: ["density", "viscosity"]})


def _closed_form_barometric(pp, rho: tuple[float, float, float], mu: tuple[float, float, float],
                            rate0: float, delta_hpa: float) -> float:
    """s/day per hPa from buoyancy and added mass alone, the arc held: with
    T = T_vac f(rho), the rate 1 - T/T0 changes by -(T_vac/T0) df, and
    T_vac/T0 = (1 - rate0) / f(rho0)."""
    omega0 = math.sqrt(pp["g"] / pp["L"])
    f = [airphys.period_factor(r, m, pp["m"], pp["bob_density"], pp["added_mass_coefficient"], pp["bob_radius"],
                               pp["boundary_layer_coefficient"], omega0) for r, m in zip(rho, mu)]
    return (1.0 - rate0 / DAY) / f[1] * (f[0] - f[2]) * DAY / (2.0 * delta_hpa)


# What barometric_point adds to the steady state's keys (a stalled clock: the state's alone).
BAROMETRIC_COLUMNS = SteadyState.COLUMNS | {
    "rate_s_per_day", "barometric_s_per_day_per_hPa", "buoyancy_s_per_day_per_hPa", "arc_s_per_day_per_hPa",
    "amplitude_deg_per_hPa", "density_kg_per_m3", "density_minus_kg_per_m3", "density_plus_kg_per_m3",
    "viscosity_Pa_s", "pressure_hPa", "delta_hPa", "torque_Nm"}


def barometric_point(clock: Clock, rates: _Rates, air: str, delta_hpa: float) -> dict:
    p0 = clock.params[air]["pressure"]
    states = [rates.at({(air, "pressure"): p0 + k * delta_hpa * HPA}) for k in (-1, 0, 1)]
    (lo, rho_lo, mu_lo), (mid, rho0, mu0), (hi, rho_hi, mu_hi) = states
    coefficient = (rate(hi) - rate(lo)) / (2.0 * delta_hpa)
    pp = clock.params[clock.pendulum]
    buoyancy = _closed_form_barometric(pp, (rho_lo, rho0, rho_hi), (mu_lo, mu0, mu_hi), rate(mid), delta_hpa)
    out = mid.as_dict()
    out.update({
        "rate_s_per_day": rate(mid),
        "barometric_s_per_day_per_hPa": coefficient,
        "buoyancy_s_per_day_per_hPa": buoyancy,
        "arc_s_per_day_per_hPa": coefficient - buoyancy,
        "amplitude_deg_per_hPa": math.degrees(hi.amplitude - lo.amplitude) / (2.0 * delta_hpa),
        "density_kg_per_m3": rho0,
        "density_minus_kg_per_m3": rho_lo,  # at pressure_hPa - delta_hPa
        "density_plus_kg_per_m3": rho_hi,
        "viscosity_Pa_s": mu0,
        "pressure_hPa": p0 / HPA,
        "delta_hPa": delta_hpa,
        "torque_Nm": rates.parameters({})[clock.escapement].get("torque") if clock.escapement else None,
    })
    return out


_BARO_KEYS = dict(_COMMON, delta_hPa=DELTA_HPA)


def _air_at(scene, point: dict, analysis: str) -> tuple[str, str, dict]:
    """(Air instance, Pendulum instance, effective parameters) at a point, else
    Invalid naming what the scene lacks (the run would refuse it)."""
    clock_check(scene, point, analysis)
    air = find_component(scene, "Air")
    if air is None:
        raise Invalid("kind", f"a scene with an Air component for {analysis}")
    return air, find_component(scene, "Pendulum"), parameters(scene, point)


def _check_pressure(scene, key: str, air: str, p0: float, delta_hpa: float) -> None:
    keys.within_fmu(scene, key, air, "pressure", (p0 - delta_hpa * HPA, p0 + delta_hpa * HPA),
                    f"the Air's pressure ({p0 / HPA:g} hPa) ± {key}")


def _check_temperature(scene, key: str, air: str, pend: str, T_air: float, T_rod: float, delta_k: float) -> None:
    keys.within_fmu(scene, key, air, "temperature", (T_air - delta_k, T_air + delta_k),
                    f"the Air's temperature ({T_air:g} K) ± {key}")
    keys.within_fmu(scene, key, pend, "temperature", (T_rod - delta_k, T_rod + delta_k),
                    f"the Pendulum's temperature ({T_rod:g} K) ± {key}")


def _check_barometric(scene, point: dict) -> None:
    air, _, params = _air_at(scene, point, "barometric_coefficient")
    _check_pressure(scene, "delta_hPa", air, params[air]["pressure"], (scene.analysis or {}).get("delta_hPa", 10.0))


@register("barometric_coefficient", set(_BARO_KEYS), keys.table_converter(_BARO_KEYS), columns=BAROMETRIC_COLUMNS,
          series=set(), check=_check_barometric)
def barometric_coefficient(scene, point: dict, progress: bool = False) -> dict:
    cfg = scene.analysis or {}
    air = _air(scene, "barometric_coefficient")
    clock = clock_at(scene, point, "barometric_coefficient")
    with _system(scene, point, clock, air) as system:
        rates = _Rates(scene, clock, system, air)
        try:
            out = barometric_point(clock, rates, air, cfg.get("delta_hPa", 10.0))
        except Stalled as e:
            out = e.state.as_dict()
        stats = rates.statistics()
    return {"kind": "barometric_coefficient", "result": out, "statistics": stats}


_THERMAL_KEYS = dict(_COMMON, delta_K=DELTA_K)


def _check_thermal(scene, point: dict) -> None:
    air, pend, params = _air_at(scene, point, "thermal_coefficient")
    _check_temperature(scene, "delta_K", air, pend, params[air]["temperature"], params[pend]["temperature"],
                       (scene.analysis or {}).get("delta_K", 2.0))


# What thermal_coefficient adds to the steady state's keys (a stalled clock: the state's alone).
THERMAL_COLUMNS = SteadyState.COLUMNS | {"rate_s_per_day", "alpha_per_K", "thermal_s_per_day_per_K",
                                         "rod_s_per_day_per_K", "air_s_per_day_per_K",
                                         "closed_form_rod_s_per_day_per_K", "delta_K"}


@register("thermal_coefficient", set(_THERMAL_KEYS), keys.table_converter(_THERMAL_KEYS), columns=THERMAL_COLUMNS,
          series=set(), check=_check_thermal)
def thermal_coefficient(scene, point: dict, progress: bool = False) -> dict:
    cfg = scene.analysis or {}
    air = _air(scene, "thermal_coefficient")
    clock = clock_at(scene, point, "thermal_coefficient")
    d = cfg.get("delta_K", 2.0)
    pend = clock.pendulum
    T_air, T_rod = clock.params[air]["temperature"], clock.params[pend]["temperature"]
    with _system(scene, point, clock, air) as system:
        rates = _Rates(scene, clock, system, air)
        try:
            mid = rates.at({})[0]
        except Stalled as e:
            return {"kind": "thermal_coefficient", "result": e.state.as_dict(), "statistics": rates.statistics()}

        def coefficient(*which: str) -> float:
            r = []
            for k in (-1, 1):
                changes = {}
                if "rod" in which:
                    changes[(pend, "temperature")] = T_rod + k * d
                if "air" in which:
                    changes[(air, "temperature")] = T_air + k * d
                r.append(rate(rates.at(changes)[0]))
            return (r[1] - r[0]) / (2.0 * d)

        try:
            total, rod, of_air = coefficient("rod", "air"), coefficient("rod"), coefficient("air")
        except Stalled as e:
            return {"kind": "thermal_coefficient", "result": e.state.as_dict(), "statistics": rates.statistics()}
        stats = rates.statistics()
    alpha = clock.params[pend]["alpha"]
    out = mid.as_dict()
    out.update({
        "rate_s_per_day": rate(mid),
        "alpha_per_K": alpha,
        "thermal_s_per_day_per_K": total,
        "rod_s_per_day_per_K": rod,
        "air_s_per_day_per_K": of_air,
        "closed_form_rod_s_per_day_per_K": airphys.thermal_rate_coefficient(alpha),
        "delta_K": d,
    })
    return {"kind": "thermal_coefficient", "result": out, "statistics": stats}


# ------------------------------------------------------------ a year of weather


def _compensating_torque(clock: Clock, rates: _Rates, air: str, delta_hpa: float, torque: float) -> tuple[float, int]:
    """The escapement torque (N.m) at which the barometric coefficient is
    zero: a bracket by doubling or halving from `torque`, then Illinois
    steps on log(torque) until the coefficient is below 1e-6 s/day per hPa
    (or the bracket below 1e-9 relative). Returns the torque and how many
    coefficients it took (two steady states each)."""
    p0 = clock.params[air]["pressure"]
    esc = clock.escapement
    count = [0]

    def coefficient(tau: float) -> float:
        rates.base = {(esc, "torque"): tau}
        count[0] += 1
        lo = rate(rates.at({(air, "pressure"): p0 - delta_hpa * HPA})[0])
        hi = rate(rates.at({(air, "pressure"): p0 + delta_hpa * HPA})[0])
        return (hi - lo) / (2.0 * delta_hpa)

    a, fa = math.log(torque), coefficient(torque)
    # Buoyancy makes a small arc lose with rising pressure (fa < 0): go up.
    factor = 2.0 if fa < 0 else 0.5
    for _ in range(8):
        b = a + math.log(factor)
        fb = coefficient(math.exp(b))
        if (fb < 0) != (fa < 0):
            break
        a, fa = b, fb
    else:
        raise SimulationError("weather_year: no compensating arc within a factor 256 of the escapement's torque")
    side = 0
    for _ in range(40):
        c = (a * fb - b * fa) / (fb - fa)
        fc = coefficient(math.exp(c))
        if abs(fc) < 1e-6 or abs(b - a) < 1e-9:
            break
        if (fc < 0) == (fa < 0):
            a, fa = c, fc
            if side == -1:
                fb *= 0.5
            side = -1
        else:
            b, fb = c, fc
            if side == 1:
                fa *= 0.5
            side = 1
    return math.exp(c), count[0]


def _quadratic(i: np.ndarray, j: np.ndarray) -> np.ndarray:
    return np.stack([np.ones_like(i), i, j, i * i, j * j, i * j], axis=-1)


class _Surface:
    """Steady states on a 3 x 3 grid of pressure (p0 +- grid_hPa) and
    temperature (T0 +- grid_K, air and rod together), with quadratics
    fitted through the rate (s/day), the amplitude (rad) and the Air's
    density and viscosity."""

    def __init__(self, rates: _Rates, clock: Clock, air: str, grid_hpa: float, grid_k: float):
        self.p0, self.T0 = clock.params[air]["pressure"], clock.params[air]["temperature"]
        self.dp, self.dT = grid_hpa * HPA, grid_k
        pend = clock.pendulum
        ij, values = [], {"rate": [], "amplitude": [], "density": [], "viscosity": []}
        for i in (-1, 0, 1):
            for j in (-1, 0, 1):
                T = self.T0 + j * grid_k
                ss, rho, mu = rates.at({(air, "pressure"): self.p0 + i * self.dp, (air, "temperature"): T,
                                        (pend, "temperature"): T})
                if i == 0 and j == 0:
                    self.centre = ss
                ij.append((i, j))
                for k, v in zip(values, (rate(ss), ss.amplitude, rho, mu)):
                    values[k].append(v)
        a = _quadratic(*map(np.array, zip(*ij)))
        self.coef = {k: np.linalg.lstsq(a, np.array(v), rcond=None)[0] for k, v in values.items()}
        self.residual = float(np.sqrt(np.mean((a @ self.coef["rate"] - np.array(values["rate"])) ** 2)))

    def __call__(self, what: str, p, T) -> np.ndarray:
        a = _quadratic((np.asarray(p) - self.p0) / self.dp, (np.asarray(T) - self.T0) / self.dT)
        return a @ self.coef[what]


def _accumulated(rate_s_per_day: np.ndarray, regulated_s_per_day: float, dt: np.ndarray) -> np.ndarray:
    """Clock error (s, positive: ahead) at each sample, the rates held over
    each interval: the clock regulated to keep time at `regulated_s_per_day`
    runs T_reg / T - 1 fast, with T = T0 (1 - r/DAY)."""
    fast = (1.0 - regulated_s_per_day / DAY) / (1.0 - rate_s_per_day / DAY) - 1.0
    return np.concatenate([[0.0], np.cumsum(fast[:-1] * dt)])


def _relaxation_time(rates: _Rates, clock: Clock, torque: float, centre: SteadyState) -> float:
    """Time constant (s) with which the amplitude settles after a change,
    from the energy balance: the escapement's work per period W = 4 tau
    phi_r against the loss D(A), so I w0^2 A dA/dt = (W - D(A)) / T and
    the time is T I w0^2 A / D'(A), with D'(A) = 4 phi_r dtau/dA measured
    by two more steady states at the torque +-1 % (Q / omega0 for linear
    damping alone)."""
    pp = clock.params[clock.pendulum]
    phi_r = clock.params[clock.escapement]["phi_r"]
    amplitudes = []
    for k in (-1, 1):
        rates.base = {(clock.escapement, "torque"): torque * (1 + 0.01 * k)}
        amplitudes.append(rates.at({})[0].amplitude)
    rates.base = {(clock.escapement, "torque"): torque}
    dA_dtau = (amplitudes[1] - amplitudes[0]) / (0.02 * torque)
    return centre.period * pp["m"] * pp["g"] * pp["L"] * centre.amplitude * dA_dtau / (4.0 * phi_r)


def _cosimulate(clock: Clock, rates: _Rates, air: str, weather: dict, hours: int,
                regulated_period: float) -> tuple[float, float, int]:
    """Run the clock through the first `hours` of the weather, each hour's
    pressure and temperature held (set on the unconnected inputs), from the
    steady state of the first hour. Returns (error s, time of the last tick
    s, ticks): the clock's reading N T_reg against the true time."""
    pend = clock.pendulum
    p, T = weather["pressure"], weather["temperature"]
    first = {(air, "pressure"): float(p[0]), (air, "temperature"): float(T[0]), (pend, "temperature"): float(T[0])}
    ss = rates.at(first)[0]
    params = rates.parameters({**first, (pend, "phi_start"): 0.0, (pend, "w_start"): ss.speed})
    system = rates.system
    system.restart(params)
    m = system.master
    t0 = m.t
    for k in range(hours):
        if k > 0:
            system.instances[air].set_values({"pressure": float(p[k]), "temperature": float(T[k])})
            system.instances[pend].set_values({"temperature": float(T[k])})
            m.ports.refresh(m.t)
            m.discontinuity()
        m.run_until(t0 + (k + 1) * 3600.0)
    ticks = system.instances[pend].get_integer(["tick_count"])[0]
    last = system.output(pend, "tick_time")
    return ticks * regulated_period - (last - t0), last - t0, ticks


_YEAR_KEYS = dict(_COMMON, delta_hPa=DELTA_HPA, days=keys.number(1, 3660, unit="days"),
                  seed=keys.count(0, 2**63 - 1),
                  check_hours=keys.count(0, 24 * 3660, also="at most 24 x days, and its co-simulation (two clocks, "
                                         "check_hours x 3600 s / master.step steps each) within the 1e10 steps bound"),
                  grid_hPa=GRID_HPA, grid_K=GRID_K,
                  seasonal_hPa=keys.number(0, 1000, unit="hPa", also=_ON_GRID_P),
                  synoptic_hPa=keys.number(0, 1000, unit="hPa", also=_ON_GRID_P),
                  seasonal_K=keys.number(0, 100, unit="K", also=_ON_GRID_T),
                  synoptic_K=keys.number(0, 100, unit="K", also=_ON_GRID_T))
_YEAR_DEFAULTS = {"delta_hPa": 10.0, "days": 365.0, "seed": 1, "check_hours": 3, "grid_hPa": 30.0, "grid_K": 8.0,
                  "seasonal_hPa": 3.0, "synoptic_hPa": 9.0, "seasonal_K": 4.0, "synoptic_K": 1.0}


@functools.lru_cache(maxsize=16)
def _weather_span(days: float, seed: int, seasonal_hpa: float, synoptic_hpa: float, seasonal_k: float,
                  synoptic_k: float) -> tuple[float, float, float, float]:
    """(lowest, highest) pressure change (hPa) and temperature change (K) of
    the year of weather about the scene's conditions: they do not depend on
    the conditions, so one year serves every sweep point."""
    w = airphys.weather_year(days=days, seed=seed, pressure_hpa=0.0, temperature_c=-273.15,
                             seasonal_hpa=seasonal_hpa, synoptic_hpa=synoptic_hpa, seasonal_k=seasonal_k,
                             synoptic_k=synoptic_k)
    p, T = w["pressure"] / HPA, w["temperature"]
    return float(p.min()), float(p.max()), float(T.min()), float(T.max())


def _check_year(scene, point: dict) -> None:
    """weather_year's keys against the scene: the steady states it takes
    (delta_hPa, the grid) and the year's weather inside the FMUs' ranges,
    the weather on the fitted grid, and the check's co-simulation bounded."""
    air, pend, params = _air_at(scene, point, "weather_year")
    esc = find_component(scene, ESCAPEMENTS)
    if esc is None or scene.components[esc].model_description.modelName != "GrasshopperEscapement":
        raise Invalid("kind", "a scene with a GrasshopperEscapement for weather_year (its torque sets the arc)")
    cfg = {**_YEAR_DEFAULTS, **(scene.analysis or {})}
    p0, T0 = params[air]["pressure"], params[air]["temperature"]
    _check_pressure(scene, "delta_hPa", air, p0, cfg["delta_hPa"])
    _check_pressure(scene, "grid_hPa", air, p0, cfg["grid_hPa"])
    # The grid moves the rod with the air: both at T0 +- grid_K.
    _check_temperature(scene, "grid_K", air, pend, T0, T0, cfg["grid_K"])
    lo_p, hi_p, lo_T, hi_T = _weather_span(cfg["days"], cfg["seed"], cfg["seasonal_hPa"], cfg["synoptic_hPa"],
                                           cfg["seasonal_K"], cfg["synoptic_K"])
    for unit, lo, hi, grid, grid_key, moved in (("hPa", lo_p, hi_p, cfg["grid_hPa"], "grid_hPa", "pressure"),
                                                ("K", lo_T, hi_T, cfg["grid_K"], "grid_K", "temperature")):
        blamed = _blamed(scene.analysis or {}, unit)
        reach = WEATHER_SPARE * grid
        if lo < -reach or hi > reach:
            raise Invalid(blamed or grid_key,
                          f"weather within {WEATHER_SPARE:g} x grid_{'hPa' if unit == 'hPa' else 'K'} = {reach:g} {unit} "
                          f"of the Air's {moved}, the grid the rates are fitted on (this year's {moved} moves by "
                          f"{lo:+.4g} to {hi:+.4g} {unit}): smaller seasonal_{unit}/synoptic_{unit} or a larger "
                          f"grid_{unit}")
    keys.within_fmu(scene, _blamed(scene.analysis or {}, "hPa") or "seasonal_hPa", air, "pressure",
                    (p0 + lo_p * HPA, p0 + hi_p * HPA), "the year's pressure")
    for inst, name in ((air, "the Air's"), (pend, "the Pendulum's")):
        keys.within_fmu(scene, _blamed(scene.analysis or {}, "K") or "seasonal_K", inst, "temperature",
                        (T0 + lo_T, T0 + hi_T), f"the year's temperature ({name})")
    hours = cfg["check_hours"]
    if hours > 24 * cfg["days"]:
        raise Invalid("check_hours", f"at most 24 x days = {24 * cfg['days']:g} hours (the year's weather is "
                                     f"{cfg['days']:g} days long)")
    steps = 2 * hours * 3600.0 / master_settings(scene, point).step
    if steps > MAX_STEPS:
        raise Invalid("check_hours", f"a check that takes at most {MAX_STEPS:.0e} communication steps (two clocks "
                                     f"over {hours} hours in steps of {master_settings(scene, point).step:g} s take "
                                     f"{steps:.3g}, hours of stepping): fewer check_hours or a longer master.step")


def _blamed(table: dict, unit: str) -> str | None:
    """Of seasonal_<unit> and synoptic_<unit>, the larger one the table sets."""
    given = [k for k in (f"seasonal_{unit}", f"synoptic_{unit}") if k in table]
    return max(given, key=lambda k: table[k]) if given else None


# The year's result: per clock (the scene's torque, the compensating one) the
# keys below prefixed "<clock>_" (the check's with check_hours > 0), and the weather's.
_CLOCKS = ("scene", "compensating")
_PER_CLOCK = ("torque_Nm", "amplitude_deg", "relaxation_time_s", "rate_rms_s_per_day", "error_after_year_s",
              "error_max_abs_s", "lag_effect_max_abs_s", "surface_fit_rms_s_per_day", "check_hours", "check_ticks",
              "check_cosimulated_error_s", "check_averaged_error_s", "check_quasi_static_error_s",
              "check_difference_s")
YEAR_COLUMNS = {"compensating_search_evaluations", "days", "pressure_rms_hPa", "temperature_rms_K"} | {
    f"{name}_{k}" for name in _CLOCKS for k in _PER_CLOCK}


def _clock_series(name: str) -> tuple[str, str]:
    """The series' (accumulated error, rate) columns of one clock."""
    return f"error_{name}_s", f"rate_{name}_s_per_day"


YEAR_SERIES = {"time", "pressure_hPa", "temperature_C", "day", *(c for n in _CLOCKS for c in _clock_series(n))}


@register("weather_year", set(_YEAR_KEYS), keys.table_converter(_YEAR_KEYS), columns=YEAR_COLUMNS,
          series=YEAR_SERIES, check=_check_year)
def weather_year(scene, point: dict, progress: bool = False) -> dict:
    cfg = scene.analysis or {}
    air = _air(scene, "weather_year")
    clock = clock_at(scene, point, "weather_year")
    if clock.escapement_model != "GrasshopperEscapement":
        raise SimulationError("weather_year needs a GrasshopperEscapement (its torque sets the arc)")
    p0, T0 = clock.params[air]["pressure"], clock.params[air]["temperature"]
    weather = airphys.weather_year(days=cfg.get("days", 365.0), seed=cfg.get("seed", 1),
                                   pressure_hpa=p0 / HPA, temperature_c=T0 - 273.15,
                                   seasonal_hpa=cfg.get("seasonal_hPa", 3.0), synoptic_hpa=cfg.get("synoptic_hPa", 9.0),
                                   seasonal_k=cfg.get("seasonal_K", 4.0), synoptic_k=cfg.get("synoptic_K", 1.0))
    t = weather["time"]
    torque = clock.params[clock.escapement]["torque"]
    series = {"time": t, "pressure_hPa": weather["pressure"] / HPA, "temperature_C": weather["temperature"] - 273.15}
    with _system(scene, point, clock, air) as system:
        rates = _Rates(scene, clock, system, air)
        try:
            return _year(cfg, clock, rates, air, weather, series, torque)
        except Stalled as e:
            raise SimulationError(f"weather_year: the clock stalls ({e.state.reason})") from None


def _year(cfg, clock: Clock, rates: _Rates, air: str, weather: dict, series: dict, torque: float) -> dict:
    t = weather["time"]
    dt = np.diff(t)
    check_hours = min(cfg.get("check_hours", 3), len(t) - 1)
    out = {}
    compensating, evaluations = _compensating_torque(clock, rates, air, cfg.get("delta_hPa", 10.0), torque)
    out["compensating_search_evaluations"] = evaluations
    pp = clock.params[clock.pendulum]
    omega0 = math.sqrt(pp["g"] / pp["L"])
    for name, tau in zip(_CLOCKS, (torque, compensating)):
        rates.base = {(clock.escapement, "torque"): tau}
        surface = _Surface(rates, clock, air, cfg.get("grid_hPa", 30.0), cfg.get("grid_K", 8.0))
        centre = surface.centre
        regulated = rate(centre)
        p, T = weather["pressure"], weather["temperature"]
        r = surface("rate", p, T)
        error = _accumulated(r, regulated, dt)
        # The averaged model with the amplitude's lag: the rate is the
        # buoyancy and added mass of the moment (period factor f of the
        # density now) times the vacuum rate of the amplitude, which
        # settles towards its steady value with the relaxation time.
        relax = _relaxation_time(rates, clock, tau, centre)
        f = np.array([airphys.period_factor(rho, mu, pp["m"], pp["bob_density"], pp["added_mass_coefficient"],
                                            pp["bob_radius"], pp["boundary_layer_coefficient"], omega0)
                      for rho, mu in zip(surface("density", p, T), surface("viscosity", p, T))])
        vacuum_ss = 1.0 - (1.0 - r / DAY) / f  # the rate 1 - T_vac/T0 of the same arc in vacuum
        vacuum = np.empty_like(vacuum_ss)
        vacuum[0] = vacuum_ss[0]
        decay = np.exp(-dt / relax)
        mean_over_step = np.empty_like(vacuum_ss)  # mean of the relaxing vacuum rate over each hour
        for k in range(len(dt)):
            gap = vacuum[k] - vacuum_ss[k]
            mean_over_step[k] = vacuum_ss[k] + gap * relax * (1.0 - decay[k]) / dt[k]
            vacuum[k + 1] = vacuum_ss[k] + gap * decay[k]
        mean_over_step[-1] = vacuum_ss[-1]
        lagged = _accumulated((1.0 - (1.0 - mean_over_step) * f) * DAY, regulated, dt)
        error_column, rate_column = _clock_series(name)
        series[error_column] = error
        series[rate_column] = r - regulated
        out.update({
            f"{name}_torque_Nm": tau,
            f"{name}_amplitude_deg": math.degrees(centre.amplitude),
            f"{name}_relaxation_time_s": relax,
            f"{name}_rate_rms_s_per_day": float(np.sqrt(np.mean((r - regulated) ** 2))),
            f"{name}_error_after_year_s": float(error[-1]),
            f"{name}_error_max_abs_s": float(np.max(np.abs(error))),
            f"{name}_lag_effect_max_abs_s": float(np.max(np.abs(lagged - error))),
            f"{name}_surface_fit_rms_s_per_day": surface.residual,
        })
        if check_hours > 0:
            cosim, elapsed, ticks = _cosimulate(clock, rates, air, weather, check_hours,
                                                centre.period)
            out.update({
                f"{name}_check_hours": check_hours,
                f"{name}_check_ticks": ticks,
                f"{name}_check_cosimulated_error_s": cosim,
                f"{name}_check_averaged_error_s": float(np.interp(elapsed, t, lagged)),
                f"{name}_check_quasi_static_error_s": float(np.interp(elapsed, t, error)),
            })
            out[f"{name}_check_difference_s"] = cosim - out[f"{name}_check_averaged_error_s"]
    stats = rates.statistics()
    out["days"] = float(t[-1] / DAY)
    out["pressure_rms_hPa"] = float(np.std(series["pressure_hPa"]))
    out["temperature_rms_K"] = float(np.std(series["temperature_C"]))
    series["day"] = t / DAY
    return {"kind": "weather_year", "result": out, "series": {k: list(map(float, v)) for k, v in series.items()},
            "statistics": stats}
