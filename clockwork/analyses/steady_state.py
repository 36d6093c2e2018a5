"""Steady state of a clock: its periodic orbit and rate errors.

``find_steady_state`` shoots for the periodic orbit (clockwork.engine.shooting)
from an amplitude guess, tells a stall from a swing, and gives the rate
errors of Ziemkiewicz: E_T = T/T0 - 1 (positive: the clock loses), the
circular error E_C of a free pendulum of the orbit's amplitude, and the
escapement error E_E = E_T - E_C. ``energy_balance_amplitude`` is the
first guess (Ziemkiewicz App. B, Hoyng Eq. 19).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from ..engine.shooting import Shooter, shoot
from ..errors import SimulationError
from ..physics import analytic
from ..scene.kinds import Invalid
from . import escapements, keys
from .context import ESCAPEMENTS, build_system, find_component, parameters
from .registry import register


@dataclass
class SteadyState:
    stalled: bool
    amplitude: float = math.nan  # rad, mean of the two turning points
    amplitude_right: float = math.nan  # rad
    amplitude_left: float = math.nan  # rad
    period: float = math.nan  # s
    E_T: float = math.nan  # T/T0 - 1 (positive: the clock loses)
    E_C: float = math.nan  # circular error of a free pendulum of this amplitude
    E_E: float = math.nan  # E_T - E_C
    iterations: int = 0
    residual: float = math.nan  # |W' - W|, rad/s
    rate_change: float = math.nan  # last change of T/T0 between iterates
    tolerance: float = math.nan  # asked-for tolerance on E_T (dimensionless)
    reason: str = ""
    speed: float = math.nan  # rad/s, the orbit's speed on the section (phi = 0, upward)

    # as_dict's keys ("reason" only with a reason)
    COLUMNS: ClassVar[frozenset[str]] = frozenset({
        "stalled", "amplitude_deg", "amplitude_right_deg", "amplitude_left_deg", "period_s", "E_T_s_per_day",
        "E_C_s_per_day", "E_E_s_per_day", "shooting_iterations", "shooting_residual_rad_per_s",
        "rate_tolerance_s_per_day", "rate_change_s_per_day", "reason"})

    def as_dict(self) -> dict:
        d = {
            "stalled": self.stalled,
            "amplitude_deg": math.degrees(self.amplitude),
            "amplitude_right_deg": math.degrees(self.amplitude_right),
            "amplitude_left_deg": math.degrees(self.amplitude_left),
            "period_s": self.period,
            "E_T_s_per_day": self.E_T * analytic.SECONDS_PER_DAY,
            "E_C_s_per_day": self.E_C * analytic.SECONDS_PER_DAY,
            "E_E_s_per_day": self.E_E * analytic.SECONDS_PER_DAY,
            "shooting_iterations": self.iterations,
            "shooting_residual_rad_per_s": self.residual,
            "rate_tolerance_s_per_day": self.tolerance * analytic.SECONDS_PER_DAY,
            "rate_change_s_per_day": self.rate_change * analytic.SECONDS_PER_DAY,
        }
        if self.reason:
            d["reason"] = self.reason
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in d.items()}


def energy_balance_amplitude(pendulum: dict, escapement_model: str | None, escapement: dict) -> float | None:
    """Amplitude (rad) at which the escapement's work per period equals the
    damping loss 2 pi E/Q with E = m L^2 omega0^2 A^2/2, or None."""
    L, m, g, Q = pendulum["L"], pendulum["m"], pendulum["g"], pendulum["Q"]
    if Q <= 0 or escapement_model is None:
        return None
    kind = escapements.escapement(escapement_model)
    if kind is None:
        return None
    work = kind.balance_work(escapement)
    if work <= 0:
        return 0.0
    return math.sqrt(work * Q / (math.pi * m * L * L * (g / L)))


def _velocity_at_zero(amplitude: float, L: float, g: float) -> float:
    """Speed at phi = 0 of a free pendulum of this amplitude (energy conservation)."""
    return math.sqrt(2.0 * g / L * (1.0 - math.cos(amplitude)))


def find_steady_state(shooter: Shooter, amplitude_guess: float, phi_r: float | None,
                      tolerance: float = 1e-3 / analytic.SECONDS_PER_DAY,
                      max_iterations: int = 30) -> SteadyState:
    """The periodic orbit from an amplitude guess (rad), its period converged
    to `tolerance` (relative); a stall when there is none above phi_r (rad)."""
    L, g = shooter.L, shooter.g
    if phi_r is not None and amplitude_guess <= phi_r:
        amplitude_guess = 1.05 * phi_r
    orbit = shoot(shooter, _velocity_at_zero(amplitude_guess, L, g), tolerance, max_iterations)
    if orbit is None:
        return SteadyState(stalled=True, iterations=1, tolerance=tolerance,
                           reason="no upward zero crossing within 3 nominal periods")
    iterations, a_right, a_left = orbit.iterations, orbit.amplitude_right, orbit.amplitude_left
    if not (a_right < math.pi and a_left < math.pi):
        return SteadyState(stalled=True, iterations=iterations, tolerance=tolerance,
                           reason="the torque drives the pendulum over the top: no swing")
    if phi_r is not None and min(a_right, a_left) <= phi_r:
        return SteadyState(stalled=True, iterations=iterations, tolerance=tolerance,
                           reason=f"amplitude {math.degrees(min(a_right, a_left)):.4g} deg does not exceed phi_r")
    amplitude = 0.5 * (a_right + a_left)
    if not amplitude < math.pi:
        return SteadyState(stalled=True, iterations=iterations, tolerance=tolerance,
                           reason="the torque drives the pendulum over the top: no swing")
    T = orbit.period
    E_T = T / shooter.T0 - 1.0
    E_C = analytic.circular_error(amplitude)
    return SteadyState(
        stalled=False, amplitude=amplitude, amplitude_right=a_right, amplitude_left=a_left,
        period=T, E_T=E_T, E_C=E_C, E_E=E_T - E_C, iterations=iterations,
        residual=abs(orbit.W_end - orbit.W), rate_change=orbit.rate_change, tolerance=tolerance,
        speed=orbit.W,
    )


# The keys of every steady-state search (shared by the kinds built on it).
# A map evaluation waits max_periods nominal periods for the pendulum's next
# tick: a swing of 150 deg takes 1.76 of them, so from 2 periods on every
# allowed guess ticks in time (a guess that did not would read as a stall).
TOLERANCE = keys.number(1e-9, 864, unit="s/day")  # from ~10x what a double resolves of a period to 1 % of a day
MAX_PERIODS = keys.count(2, 1000)
AMPLITUDE_GUESS = keys.angle_in(0, 150)
_KEYS = {"tolerance_s_per_day": TOLERANCE, "max_periods": MAX_PERIODS, "amplitude_guess": AMPLITUDE_GUESS}


def clock_check(scene, point: dict, analysis: str) -> None:
    """What a steady-state kind needs of the scene at a point (as clock_at
    does at run time), else Invalid: a Pendulum, and a first amplitude
    guess, analysis.amplitude_guess or the escapement's energy balance."""
    pendulum = find_component(scene, "Pendulum")
    if pendulum is None:
        raise Invalid("kind", f"a scene with a Pendulum component for {analysis}")
    if (scene.analysis or {}).get("amplitude_guess"):
        return
    escapement = find_component(scene, ESCAPEMENTS)
    params = parameters(scene, point)
    model = scene.components[escapement].model_description.modelName if escapement else None
    if energy_balance_amplitude(params[pendulum], model, params.get(escapement, {})) is None:
        raise Invalid("amplitude_guess", "an amplitude guess: this clock has no energy balance to start from "
                                         "(no escapement of a known kind, or Q = 0)")


@dataclass
class Clock:
    """A scene's clock at a sweep point, as the steady-state analyses see it."""

    pendulum: str
    escapement: str | None
    escapement_model: str | None
    params: dict  # {instance: Parameters}
    min_amplitude: float | None  # rad: a swing must exceed it (phi_r, alpha_m2)
    guess: float | None  # rad, the first amplitude guess
    tolerance: float  # relative, on the period


def clock_at(scene, point: dict, analysis: str) -> Clock:
    """The pendulum, escapement, parameters, amplitude guess and tolerance."""
    cfg = scene.analysis or {}
    pendulum = find_component(scene, "Pendulum")
    if pendulum is None:
        raise SimulationError(f"the {analysis} analysis needs a Pendulum component")
    escapement = find_component(scene, ESCAPEMENTS)
    params = parameters(scene, point)
    pp = params[pendulum]
    esc_model = scene.components[escapement].model_description.modelName if escapement else None
    esc = params.get(escapement, {})
    kind = escapements.escapement(esc_model)
    a_min = kind.min_amplitude(esc) if kind else None
    guess = cfg.get("amplitude_guess") or energy_balance_amplitude(pp, esc_model, esc)
    if guess is None:
        raise SimulationError(f"{analysis}: give analysis.amplitude_guess (no energy balance for this escapement)")
    tolerance = cfg.get("tolerance_s_per_day", 1e-3) / analytic.SECONDS_PER_DAY
    return Clock(pendulum, escapement, esc_model, params, a_min, guess, tolerance)


# Every key of a steady_state result: SteadyState.as_dict's, and what steady_state adds.
COLUMNS = SteadyState.COLUMNS | {"torque_Nm", "energy_balance_amplitude_deg", "E_E_B7_s_per_day"}


@register("steady_state", set(_KEYS), keys.table_converter(_KEYS), columns=COLUMNS, series=set(),
          check=lambda scene, point: clock_check(scene, point, "steady_state"))
def steady_state(scene, point: dict, progress: bool = False) -> dict:
    cfg = scene.analysis or {}
    clock = clock_at(scene, point, "steady_state")
    pendulum, escapement, esc_model, params = clock.pendulum, clock.escapement, clock.escapement_model, clock.params
    pp = params[pendulum]
    esc = params.get(escapement, {})
    guess, tolerance = clock.guess, clock.tolerance
    system = build_system(scene, point, record={pendulum: ["tick_time", "tick_w", "amplitude"]})
    with system:
        shooter = Shooter(system.master, params, pendulum, pp,
                          max_period_factor=float(cfg.get("max_periods", 3)))
        if guess <= 0:
            result = None
        else:
            result = find_steady_state(shooter, guess, clock.min_amplitude, tolerance=tolerance)
        stats = vars(system.master.stats).copy()
    if result is None:
        result = SteadyState(stalled=True, tolerance=tolerance, reason="no driving torque")
    out = result.as_dict()
    torque = esc.get("torque") if escapement else None
    out["torque_Nm"] = torque
    out["energy_balance_amplitude_deg"] = math.degrees(guess) if guess else None
    if esc_model == escapements.GRASSHOPPER and not result.stalled and pp["Q"] > 0:
        out["E_E_B7_s_per_day"] = analytic.escapement_error_B7(result.amplitude, esc["phi_r"], pp["Q"]) * analytic.SECONDS_PER_DAY
    return {"kind": "steady_state", "result": out, "statistics": stats}
