"""Every analysis key of every analysis kind range-checked at validate.

The class, not the examples: each key of each registered kind is a
``keys.Key`` with a bound stated in docs/scenes.md (the table is the
registry's); every kind whose keys depend on the scene has a check run at
every sweep point; hostile values of every key of every kind, given as
``--set`` to a bundled scene of the kind, are refused in one line naming the
key; and what the runs used to refuse (a value the FMU does not take, a kick
or a jump outside the experiment, a sample grid off the steps), or to
compute wrongly (weather off the fitted grid), validate now refuses, and run
refuses the same way before any work.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from cwtest import FMU_DIR, ROOT, assert_one_line_error, fmu_file, run_cli
import clockwork.run.catalog  # noqa: F401  (registers every kind)
from clockwork.analyses import keys, registry


@pytest.fixture(autouse=True)
def _fmus(monkeypatch, tmp_path):
    fmu_file("Pendulum")
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))
    monkeypatch.setenv("CLOCKWORK_CACHE", str(tmp_path / "cache"))


# A bundled scene of each kind (time_series and ticks have no keys).
SCENE_OF = {
    "steady_state": "ziemkiewicz_fig4a", "escapement_steady_state": "ziemkiewicz_fig2a",
    "steady_orbit": "ziemkiewicz_fig3", "disturbance": "ziemkiewicz_fig7a", "free_period": "ziemkiewicz_fig1",
    "limit_cycle": "ziemkiewicz_fig8a", "rate_error": "ziemkiewicz_fig10a", "lyapunov": "ziemkiewicz_fig10b",
    "step_accuracy": "ziemkiewicz_fig11", "vibration_series": "ziemkiewicz_fig9a", "poincare": "ziemkiewicz_fig9b",
    "hoyng_stationary": "hoyng_appC", "hoyng_torque_jump": "hoyng_fig4", "hoyng_long_run": "hoyng_fig6",
    "hoyng_averaged_run": "hoyng_fig6_averaged", "barometric_coefficient": "air_barometric_ziemkiewicz",
    "thermal_coefficient": "air_thermal", "weather_year": "air_weather_year",
}
KINDS_WITH_KEYS = sorted(k for k, v in registry.ANALYSIS_KEYS.items() if v)


def test_every_kind_with_keys_has_a_scene_here():
    assert set(KINDS_WITH_KEYS) <= set(SCENE_OF), set(KINDS_WITH_KEYS) - set(SCENE_OF)


@pytest.mark.parametrize("kind", KINDS_WITH_KEYS)
def test_every_key_is_a_key_with_a_bound(kind):
    specs = registry.key_specs(kind)
    assert set(specs) == registry.ANALYSIS_KEYS[kind], kind
    for key, spec in specs.items():
        assert isinstance(spec, keys.Key), (kind, key)
        assert spec.bound, (kind, key)


@pytest.mark.parametrize("kind", KINDS_WITH_KEYS)
def test_a_kind_whose_keys_depend_on_the_scene_has_a_check(kind):
    if any(spec.also for spec in registry.key_specs(kind).values()):
        assert kind in registry.CHECKS, kind


def test_docs_state_every_bound():
    docs = (ROOT / "docs" / "scenes.md").read_text()
    rows = registry.key_table()
    missing = [r for r in rows if r not in docs]
    assert not missing, "docs/scenes.md lacks (or states otherwise):\n" + "\n".join(missing)
    assert len(rows) >= 40


# --- every key of every kind, hostile values --------------------------------------------

# Values of every kind that no key accepts: the wrong type, NaN/inf spelled in
# TOML, and numbers far outside any bound.
HOSTILE = ['"abc"', "true", "[1, 2]", "{ a = 1 }", "nan", "inf", "-inf", "-1e300", "1e300", "-1",
           "100000000000000000000"]


def _cases():
    for kind in KINDS_WITH_KEYS:
        for key in sorted(registry.ANALYSIS_KEYS[kind]):
            for value in HOSTILE:
                yield pytest.param(kind, key, value, id=f"{kind}.{key}={value}")


def _refused_alone(spec: keys.Key, toml_value: str) -> bool:
    import tomllib

    v = tomllib.loads(f"x = {toml_value}")["x"]
    try:
        spec("x", v)
    except Exception:
        return True
    return False


@pytest.mark.parametrize("kind, key, value", list(_cases()))
def test_hostile_values_of_every_key_are_one_line(capsys, kind, key, value):
    """Refused in one line naming the key where the key's own bound refuses
    it; where the bound takes it (e.g. 1e300 for an unbounded time), the
    scene checks may refuse it, always naming the key; never a traceback."""
    rc, out, err = run_cli(capsys, ["validate", SCENE_OF[kind], "--set", f"analysis.{key}={value}"])
    assert "Traceback" not in err
    if _refused_alone(registry.key_specs(kind)[key], value):
        assert_one_line_error(rc, err, f"--set analysis.{key}")
    elif rc != 0:
        assert_one_line_error(rc, err, "analysis.")


# --- what run refused (or got wrong), validate refuses now -------------------------------

REFUSED = {
    # The cases: values the Air or Pendulum FMU does not take, or weather off the fitted grid.
    "grid_K moves the temperature below the FMUs' range": ("air_weather_year", "analysis.grid_K=95", "grid_K"),
    "grid_K = 300": ("air_weather_year", "analysis.grid_K=300", "grid_K"),
    "delta_hPa beyond the Air's pressures": ("air_weather_year", "analysis.delta_hPa=999", "delta_hPa"),
    "delta_hPa = 5000": ("air_weather_year", "analysis.delta_hPa=5000", "delta_hPa"),
    "grid_hPa = 1e300": ("air_weather_year", "analysis.grid_hPa=1e300", "grid_hPa"),
    "grid_hPa beyond the Air's pressures": ("air_weather_year", "analysis.grid_hPa=999", "grid_hPa"),
    "synoptic_K = 500 (math domain error)": ("air_weather_year", "analysis.synoptic_K=500", "synoptic_K"),
    "synoptic_K off the grid": ("air_weather_year", "analysis.synoptic_K=50", "synoptic_K"),
    "seasonal_hPa = 2000 (weather of 2437 hPa)": ("air_weather_year", "analysis.seasonal_hPa=2000", "seasonal_hPa"),
    "seasonal_hPa off the grid": ("air_weather_year", "analysis.seasonal_hPa=200", "seasonal_hPa"),
    "a grid too fine for the weather": ("air_weather_year", "analysis.grid_hPa=1", "grid_hPa"),
    "check_hours = 100000 (1.3e10 steps)": ("air_weather_year", "analysis.check_hours=100000", "check_hours"),
    "check_hours beyond the year": ("air_weather_year", "analysis.check_hours=10000", "check_hours"),
    "check_hours over the steps bound": ("air_weather_year", "analysis.check_hours=8760", "check_hours"),
    "delta_K beyond the Air's temperatures": ("air_thermal", "analysis.delta_K=99", "delta_K"),
    "barometric delta_hPa beyond the Air's pressures": ("air_barometric_ziemkiewicz", "analysis.delta_hPa=999",
                                                        "delta_hPa"),
    # The other kinds: what their runs refused.
    "a jump after the experiment": ("hoyng_fig4", "analysis.jump_at_periods=1e6", "jump_at_periods"),
    "a torque the escapement does not take": ("hoyng_fig4", "analysis.torque_after=2000", "torque_after"),
    "samples off the blocks": ("hoyng_fig6_averaged", "analysis.sample_periods=501", "sample_periods"),
    "noise that never starts": ("hoyng_fig6_averaged", "analysis.noise_start=1e9", "noise_start"),
    "an averaged amplitude over the top": ("hoyng_fig6_averaged", "analysis.torque=1", "torque"),
    "a kick after the experiment": ("ziemkiewicz_fig7a", "analysis.kick_time=1e6", "kick_time"),
    "a kick that does not end": ("ziemkiewicz_fig7a", "analysis.kick_duration=1e6", "kick_duration"),
    "an amplitude target below phi_r": ("ziemkiewicz_fig3", 'analysis.amplitude="1 deg"', "amplitude"),
    "a fit that starts after the end": ("ziemkiewicz_fig10b", "analysis.fit_start=2000", "fit_start"),
    "a twin past the top": ("ziemkiewicz_fig10b", 'analysis.perturbation="179 deg"', "perturbation"),
    "samples off the steps": ("ziemkiewicz_fig9a", 'analysis.sample_interval="1.5 ms"', "sample_interval"),
    "a transient that leaves no samples": ("ziemkiewicz_fig9a", "analysis.transient=299.999", "transient"),
    "a sample interval longer than the run": ("ziemkiewicz_fig8a", "analysis.sample_interval=100", "sample_interval"),
    "a transient longer than the run": ("ziemkiewicz_fig10a", "analysis.transient=5000", "transient"),
    "a Poincare transient longer than the run": ("ziemkiewicz_fig9b", "analysis.transient=5000", "transient"),
    "an rtol the Pendulum does not take": ("ziemkiewicz_fig11", "analysis.rtols=[1e-16]", "rtols"),
    "a fixed step the Pendulum does not take": ("ziemkiewicz_fig11", "analysis.fixed_steps=[2e9]", "fixed_steps"),
    "a guess that never ticks in time": ("ziemkiewicz_fig4a", 'analysis.amplitude_guess="179 deg"',
                                         "amplitude_guess"),
    "a shooting window shorter than a period": ("ziemkiewicz_fig4a", "analysis.max_periods=1", "max_periods"),
    "a tolerance below what doubles resolve": ("ziemkiewicz_fig4a", "analysis.tolerance_s_per_day=1e-15",
                                               "tolerance_s_per_day"),
    "a key that did nothing": ("hoyng_appC", "analysis.measure_periods=3", "measure_periods"),
}


@pytest.mark.parametrize("case", list(REFUSED))
def test_validate_refuses_what_run_refused(capsys, tmp_path, case):
    scene, override, key = REFUSED[case]
    rc, _, err = run_cli(capsys, ["validate", scene, "--set", override])
    assert_one_line_error(rc, err, f"analysis.{key}")
    out = tmp_path / "out"
    rc, _, err2 = run_cli(capsys, ["run", scene, "--set", override, "--out", out, "--no-progress"])
    assert_one_line_error(rc, err2, f"analysis.{key}")
    assert err2 == err
    assert not out.exists() or not any(out.iterdir())


def test_the_weather_check_is_exact_about_the_grid():
    """The weather's excursion is computed, not estimated: the default year
    (seed 1: -29.1 to +26.0 hPa) fits 1.5 x a grid of 20 hPa (30 hPa) and
    not 1.5 x 19 hPa (28.5 hPa)."""
    from clockwork.analyses.environment import _weather_span

    lo, hi, _, _ = _weather_span(365.0, 1, 3.0, 9.0, 4.0, 1.0)
    assert 28.5 < -lo < 30 and hi < 28.5


@pytest.mark.parametrize("override", ["analysis.grid_hPa=20", "analysis.grid_K=79", "analysis.delta_hPa=900",
                                      "analysis.seed=2", "analysis.days=1", "analysis.check_hours=24"])
def test_values_inside_every_bound_pass(capsys, override):
    rc, out, err = run_cli(capsys, ["validate", "air_weather_year", "--set", override])
    assert rc == 0, err


def test_a_sweep_point_outside_names_the_point(capsys, tmp_path):
    """The checks run at every sweep point: the Air's pressure swept so that
    one point's pressure - delta_hPa leaves the FMU's range."""
    text = (ROOT / "scenarios" / "air_barometric_ziemkiewicz.toml").read_text()
    scene = tmp_path / "s.toml"
    scene.write_text(text)
    rc, _, err = run_cli(capsys, ["validate", scene, "--set", "analysis.delta_hPa=500"])
    assert rc == 0, err
    rc, _, err = run_cli(capsys, ["validate", scene, "--set", "analysis.delta_hPa=500",
                                  "--set", "air.pressure=\"1400 hPa\""])
    assert rc == 0, err
    rc, _, err = run_cli(capsys, ["validate", scene, "--set", "analysis.delta_hPa=500",
                                  "--set", "air.pressure=\"1600 hPa\""])
    assert_one_line_error(rc, err, "analysis.delta_hPa", "[1000, 200000] Pa")
