"""The Air FMU against published values, and the Pendulum and Drag in air
against their closed forms.

Air: CIPM-2007 density (Picard et al., Metrologia 45, 149 (2008)) and
Sutherland's viscosity with the usual constants for air. Pendulum: a free, undamped
pendulum in still air swings with the period of the vacuum scaled by
sqrt((m + m_a)/(m - rho V)) (buoyancy and added mass, Nelson and Olsson
1986) and by sqrt(1 + alpha dT) (the rod), exactly: the equation is the
vacuum's with g and L rescaled. With the air off (the defaults) nothing
changes, bit for bit.
"""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from fmpy import simulate_fmu

from cwtest import fmu_file
from fmu_driver import OK, Instance
from clockwork.physics import air as airphys


def air(pressure: float, temperature: float, humidity: float, **params) -> dict:
    with Instance(fmu_file("Air"), params, {"pressure": pressure, "temperature": temperature,
                                             "humidity": humidity}) as a:
        return {n: a.get(n) for n in ("density", "viscosity", "vapour_fraction", "compressibility")}


def test_fmpy_validate_is_clean():
    p = subprocess.run([sys.executable, "-m", "fmpy", "validate", str(fmu_file("Air"))],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0 and "No problems found." in p.stdout, p.stdout + p.stderr


def test_cipm_density_of_moist_air_at_20_degC():
    """1.1992 kg/m^3 at 20 degC, 101325 Pa, 50 % RH, quoted to four
    decimals; the CO2 fraction behind a quoted value moves the fourth
    (100 ppm: 5e-5 kg/m^3), so 2e-4 is the comparison's resolution."""
    a = air(101325.0, 293.15, 0.5)
    assert abs(a["density"] - 1.1992) < 2e-4, a
    # The saturation vapour pressure behind x_v: 2339.2 Pa at 20 degC
    # (IAPWS: 2.3392 kPa), f(p, t) = 1.00062 + 3.14e-8 p + 5.6e-7 t^2.
    f = 1.00062 + 3.14e-8 * 101325.0 + 5.6e-7 * 20.0 ** 2
    p_sv = a["vapour_fraction"] * 101325.0 / (0.5 * f)
    assert abs(p_sv - 2339.2) < 1.0, p_sv


def test_dry_air_at_0_degC():
    """Dry air at 0 degC, 101325 Pa: 1.2922 kg/m^3 as an ideal gas of
    M = 28.96546 g/mol (density x Z), 1.293 with CIPM-2007's
    compressibility (Z = 0.99942)."""
    a = air(101325.0, 273.15, 0.0)
    assert a["vapour_fraction"] == 0.0
    assert abs(a["density"] * a["compressibility"] - 1.2922) < 1e-4, a
    assert abs(a["density"] - 1.2930) < 1e-4, a
    assert 0.9993 < a["compressibility"] < 0.9996


def test_sutherland_viscosity():
    """1.716e-5 Pa s at 0 degC (the law's reference) and 1.813e-5 at
    20 degC (tables of air: 1.81e-5); humidity does not enter."""
    assert air(101325.0, 273.15, 0.0)["viscosity"] == pytest.approx(1.716e-5, rel=1e-14)
    mu = air(90000.0, 293.15, 0.9)["viscosity"]
    assert abs(mu - 1.813e-5) < 5e-9, mu
    assert mu == air(101325.0, 293.15, 0.0)["viscosity"]


def test_density_follows_pressure_temperature_and_humidity():
    dry = air(101325.0, 293.15, 0.0)["density"]
    # Dry air is nearly ideal: density in proportion to pressure, but for Z (1e-5 per 1000 Pa).
    assert air(102325.0, 293.15, 0.0)["density"] / dry - 1.0 == pytest.approx(1000.0 / 101325.0, rel=1e-3)
    base = air(101325.0, 293.15, 0.5)["density"]
    assert air(101325.0, 303.15, 0.5)["density"] < base  # warmer: thinner
    assert air(101325.0, 293.15, 1.0)["density"] < base  # water vapour is lighter than air
    assert air(101325.0, 293.15, 0.5, x_CO2=0.0005)["density"] > base


def test_outputs_follow_time_varying_inputs():
    t = np.linspace(0.0, 10.0, 11)
    signal = np.array(list(zip(t, 101325.0 + 100.0 * t)), dtype=[("time", float), ("pressure", float)])
    r = simulate_fmu(str(fmu_file("Air")), stop_time=10.0, output_interval=1.0, input=signal,
                     start_values={"temperature": 293.15, "humidity": 0.5}, output=["density"])
    # fmpy reads a feedthrough output after the step, with the inputs set
    # before it: the sample at t shows the pressure at t - 1 s.
    assert np.all(np.diff(r["density"][1:]) > 0), r["density"]
    assert r["density"][-1] == pytest.approx(air(102225.0, 293.15, 0.5)["density"], rel=1e-12)


@pytest.mark.parametrize("bad", [{"pressure": -1.0}, {"humidity": 1.5}, {"temperature": 10.0}])
def test_out_of_range_inputs_are_refused(bad):
    with Instance(fmu_file("Air")) as a:
        assert a.set(**bad) != OK


# ------------------------------------------------------------ Pendulum in air


def _period(params: dict, inputs: dict) -> float:
    """The free, undamped pendulum's period from its tick outputs."""
    base = {"Q": 0.0, "phi_start": 0.05, "rtol": 1e-12, "atol": 1e-15}
    with Instance(fmu_file("Pendulum"), {**base, **params}, inputs) as p:
        while p.get("tick_count") < 3:
            assert p.step(0.25) == OK
        return p.get("period")


def test_buoyancy_and_added_mass_scale_the_period_as_the_closed_form():
    """A brass sphere of 1 kg (R = 30.5 mm) in air of 1.2 kg/m^3: the period
    grows by sqrt((m + m_a)/(m - rho V)), m_a with the potential flow's 1/2
    and the Stokes boundary layer's 9/4 delta/R (about 1.5e-4 together)."""
    rho, mu = 1.2, 1.8e-5
    radius = airphys.sphere_radius(1.0, 8400.0)
    air_params = {"bob_density": 8400.0, "bob_radius": radius, "added_mass_coefficient": 0.5,
                  "boundary_layer_coefficient": 2.25}
    vacuum = _period(air_params, {})
    in_air = _period(air_params, {"rho_air": rho, "mu_air": mu})
    factor = airphys.period_factor(rho, mu, 1.0, 8400.0, 0.5, radius, 2.25, math.sqrt(9.81))
    assert factor - 1.0 > 1e-4
    assert in_air / vacuum == pytest.approx(factor, rel=1e-10)
    # A cylinder across the flow: added-mass coefficient 1, no boundary layer.
    cyl = _period({"bob_density": 8400.0, "added_mass_coefficient": 1.0}, {"rho_air": rho})
    assert cyl / vacuum == pytest.approx(math.sqrt((1.0 + rho / 8400.0) / (1.0 - rho / 8400.0)), rel=1e-10)


@pytest.mark.parametrize("alpha", [airphys.ALPHA_STEEL, airphys.ALPHA_INVAR])
def test_rod_expansion_scales_the_period(alpha):
    """10 K above T_ref the rod is L (1 + 10 alpha): the period grows by the root."""
    cold = _period({"alpha": alpha}, {})
    warm = _period({"alpha": alpha}, {"temperature": 303.15})
    assert warm / cold == pytest.approx(math.sqrt(1.0 + 10.0 * alpha), rel=1e-10)


def _trace(params: dict, inputs: dict) -> list[float]:
    out = []
    with Instance(fmu_file("Pendulum"), {"phi_start": 0.2, "Q": 300.0, **params},
                  {"tau_external": 0.01, **inputs}) as p:
        for _ in range(300):
            assert p.step(0.013) == OK
            out += [p.get(n) for n in ("phi", "w", "a", "energy", "tick_time", "period", "amplitude")]
    return out


def test_air_off_is_bit_for_bit_the_vacuum_pendulum():
    """Density 0 with every air parameter set, and alpha set at T = T_ref:
    every factor is exactly 1, so every output equals the default's."""
    default = _trace({}, {})
    off = _trace({"bob_density": 2000.0, "bob_radius": 0.05, "added_mass_coefficient": 1.0, "alpha": 1e-5,
                  "T_ref": 290.0}, {"rho_air": 0.0, "mu_air": 1.8e-5, "temperature": 290.0})
    assert off == default
    assert _trace({}, {"rho_air": 1.2}) != default


# ------------------------------------------------------------ Drag in air


def test_drag_of_a_sphere_in_air():
    """tau = -(6 pi mu R (1 + R/delta) arm^2 w + rho C_D pi R^2 arm^3 w|w| / 2),
    delta = sqrt(2 mu / (rho omega)), on top of c1 and c2."""
    rho, mu, R, arm, cd, omega = 1.2, 1.8e-5, 0.03, 0.9, 0.47, 3.0
    c1, c2 = 1e-5, 2e-5
    delta = math.sqrt(2.0 * mu / (rho * omega))
    for w in (0.4, -0.25):
        with Instance(fmu_file("Drag"), {"c1": c1, "c2": c2, "bob_radius": R, "arm": arm, "drag_coefficient": cd,
                                        "omega": omega}, {"w": w, "rho_air": rho, "mu_air": mu}) as d:
            expected = -((c1 + 6 * math.pi * mu * R * (1 + R / delta) * arm ** 2) * w
                         + (c2 + 0.5 * rho * cd * math.pi * R ** 2 * arm ** 3) * w * abs(w))
            assert d.get("tau") == pytest.approx(expected, rel=1e-13)
    # No bob radius: the air terms are off whatever the air.
    with Instance(fmu_file("Drag"), {"c1": c1, "c2": c2}, {"w": 0.4, "rho_air": rho, "mu_air": mu}) as d:
        assert d.get("tau") == -(c1 * 0.4 + c2 * 0.4 * 0.4)


def test_the_air_factors_follow_every_change_at_once():
    """The Pendulum keeps its air factors while the air holds still (they
    cost square roots and divisions at every step, output and derivative).
    After any change (an air input set, an input derivative given and taken
    back, an FMU state restored, the instance reset and started again) its
    acceleration and the step after it are those of a second instance given
    the same state afresh."""
    params = {"phi_start": 0.2, "Q": 300.0, "alpha": 1e-3, "T_ref": 290.0, "bob_radius": 0.05,
              "added_mass_coefficient": 1.0}
    inputs = {"rho_air": 1.2, "mu_air": 1.8e-5, "temperature": 290.0}
    with Instance(fmu_file("Pendulum"), params, inputs) as p, \
         Instance(fmu_file("Pendulum"), params, inputs, name="fresh") as fresh:
        assert p.step(0.05) == OK
        before, before_time = p.get_state(), p.time

        def same_as_fresh(what):
            state = p.get_state()
            assert fresh.set_state(state) == OK
            fresh.time = p.time
            p.free_state(state)
            assert p.get_many(["a", "energy"]) == fresh.get_many(["a", "energy"]), what
            assert p.output_derivative("w", 2) == fresh.output_derivative("w", 2), what
            assert p.step(0.05) == OK and fresh.step(0.05) == OK
            assert p.get_many(["phi", "w", "a"]) == fresh.get_many(["phi", "w", "a"]), what

        changes = [("rho_air", lambda: p.set(rho_air=0.9)),
                   ("mu_air", lambda: p.set(mu_air=2.5e-5)),
                   ("temperature", lambda: p.set(temperature=310.0)),
                   ("an input derivative and back", lambda: (p.set_input_derivatives({"temperature": {1: 0.5}}),
                                                             p.step(0.02), p.set(temperature=300.0))),
                   ("a state restored", lambda: (p.set_state(before), setattr(p, "time", before_time)))]
        for what, change in changes:
            p.get("a")  # the factors are kept now
            change()
            same_as_fresh(what)
        p.free_state(before)
        p.get("a")
        p.check(p.raw.fmi2Reset(p.c), "fmi2Reset")
        p.initialize({**params, "alpha": 5e-4}, inputs)
        fresh.check(fresh.raw.fmi2Reset(fresh.c), "fmi2Reset")
        fresh.initialize({**params, "alpha": 5e-4}, inputs)
        assert p.get_many(["a", "energy"]) == fresh.get_many(["a", "energy"])
        same_as_fresh("reset")
