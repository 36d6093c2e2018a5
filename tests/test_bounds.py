"""Bounds known before the work starts: what a run records, and sweeps that
repeat a point. (The FMU archive bounds are in test_fmu_hardening.py.)"""

from __future__ import annotations

import pytest

from cwtest import CLOCK_SCENE, FMU_DIR, assert_one_line_error, fmu_file, run_cli


@pytest.fixture(autouse=True)
def _env(monkeypatch, tmp_path):
    fmu_file("Pendulum")
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))
    monkeypatch.setenv("CLOCKWORK_CACHE", str(tmp_path / "cache"))


def _scene(tmp_path, stop=1.0, sweep="", edit=lambda s: s):
    f = tmp_path / "s.toml"
    f.write_text(edit(CLOCK_SCENE.format(stop=stop, sweep=sweep)))
    return f


# Each records far more than memory holds; each must be refused by validate and run, before any work.
UNBOUNDED = {
    "stop = 1e12 s": dict(stop=1e12),
    "a tiny step": dict(stop=1000, edit=lambda s: s.replace('step = "0.01 s"', 'step = "1e-7 s"')),
    # a single run's series goes to disk as it is recorded (test_streaming.py): a sweep's points are kept
    "a tiny record interval in a sweep": dict(
        stop=1e5, edit=lambda s: s.replace("[record]", '[record]\ninterval = "1e-3 s"'),
        sweep='\n[sweep]\naxes = [ { parameter = "pendulum.Q", values = [500, 1000] } ]\n'),
    "ticks only": dict(stop=1e12, edit=lambda s: s.replace('outputs = ["pendulum.phi"]', "outputs = []")),
    "many outputs": dict(stop=1e6, edit=lambda s: s.replace('outputs = ["pendulum.phi"]', 'outputs = ["pendulum.phi", '
                                                             '"pendulum.w", "escapement.tau", "escapement.mode"]')),
    "a swept stop": dict(sweep='\n[sweep]\naxes = [ { parameter = "experiment.stop", values = [1, 1e11] } ]\n'),
}


@pytest.mark.parametrize("case", list(UNBOUNDED))
@pytest.mark.parametrize("command", ["validate", "run"])
def test_a_run_that_would_record_without_bound_is_refused_before_it_starts(capsys, tmp_path, case, command):
    f = _scene(tmp_path, **UNBOUNDED[case])
    argv = [command, f] + (["--out", tmp_path / "out", "--no-progress"] if command == "run" else [])
    rc, _, err = run_cli(capsys, argv)
    assert_one_line_error(rc, err, str(f), "experiment.stop", "record.interval", code=2)
    assert not (tmp_path / "out").exists()


def test_an_override_past_the_bound_is_refused(capsys, tmp_path):
    f = _scene(tmp_path)
    rc, _, err = run_cli(capsys, ["validate", f, "--set", "experiment.stop=1e12"])
    assert_one_line_error(rc, err, "experiment.stop", code=2)


def test_a_long_run_with_a_record_interval_is_accepted(capsys, tmp_path):
    f = _scene(tmp_path, stop=1e6, edit=lambda s: s.replace("[record]", '[record]\ninterval = "100 s"')
               .replace('ticks = "pendulum"', ""))
    rc, out, err = run_cli(capsys, ["validate", f])
    assert rc == 0 and out.startswith("ok"), err


# --- sweeps that repeat a point -------------------------------------------------------

REPEATS = {
    "150,000 identical values": ('{ parameter = "pendulum.Q", values = [' + ",".join(["1e3"] * 150_000) + "] }",
                                 "", "sweep.axes[0]"),
    "one value twice": ('{ parameter = "pendulum.Q", values = [500, 1000, 500] }', "", "sweep.axes[0]"),
    "the same value in other units": ('{ parameter = "escapement.torque", values = ["0.4 N.cm", "0.004 N.m"] }',
                                      "", "sweep.axes[0]"),
    "start = stop": ('{ parameter = "pendulum.Q", start = 1000, stop = 1000, num = 5 }', "", "sweep.axes[0]"),
    "a grid with a repeated second axis": ('{ parameter = "pendulum.Q", values = [500, 1000] }, '
                                           '{ parameter = "master.step", values = ["0.01 s", "0.01 s"] }',
                                           "", "sweep.axes[1]"),
    "a zip with a repeated pair": ('{ parameter = "pendulum.Q", values = [500, 1000, 500] }, '
                                   '{ parameter = "escapement.torque", values = ["0.4 N.cm", "0.5 N.cm", "0.4 N.cm"] }',
                                   'mode = "zip"\n', "sweep.axes"),
}


@pytest.mark.parametrize("case", list(REPEATS))
def test_a_sweep_that_repeats_a_point_is_refused(capsys, tmp_path, case):
    axes, mode, key = REPEATS[case]
    f = _scene(tmp_path, stop=0.1, sweep=f"\n[sweep]\n{mode}axes = [ {axes} ]\n")
    rc, _, err = run_cli(capsys, ["validate", f])
    assert_one_line_error(rc, err, str(f), key, "repeats", code=2)


def test_a_zip_whose_axes_repeat_values_but_not_points_is_accepted(capsys, tmp_path):
    axes = ('{ parameter = "pendulum.Q", values = [500, 1000, 500] }, '
            '{ parameter = "escapement.torque", values = ["0.4 N.cm", "0.5 N.cm", "0.6 N.cm"] }')
    f = _scene(tmp_path, stop=0.1, sweep=f'\n[sweep]\nmode = "zip"\naxes = [ {axes} ]\n')
    rc, out, err = run_cli(capsys, ["validate", f])
    assert rc == 0 and "3 sweep points" in out, err


# --- every analysis kind: memory and steps known before the work -------------------------

# (bundled scene, overrides, the key the one line must name). Each would keep
# far more than memory holds or step for days; validate and run refuse it.
KIND_CASES = {
    "hoyng_long_run, 10x the span (memory)": ("hoyng_fig6", ["experiment.stop=3e8"], "experiment.stop"),
    "hoyng_long_run, stop = 1e13 (steps)": ("hoyng_fig6", ["experiment.stop=1e13"], "experiment.stop"),
    "hoyng_averaged_run, stop = 1e12": ("hoyng_fig6_averaged", ["experiment.stop=1e12"], "experiment.stop"),
    "hoyng_torque_jump, stop = 1e9": ("hoyng_fig4", ["experiment.stop=1e9"], "experiment.stop"),
    "lyapunov, a tiny sample_interval": ("ziemkiewicz_fig10b", ["analysis.sample_interval=1e-6"],
                                         "analysis.sample_interval"),
    "vibration_series, a tiny sample_interval": ("ziemkiewicz_fig8b", ["analysis.sample_interval=1e-7"],
                                                 "analysis.sample_interval"),
    "limit_cycle, stop = 1e9": ("ziemkiewicz_fig8a", ["experiment.stop=1e9"], "experiment.stop"),
    "rate_error, stop = 1e9": ("ziemkiewicz_fig10a", ["experiment.stop=1e9"], "experiment.stop"),
    "poincare, stop = 1e9": ("ziemkiewicz_fig9b", ["experiment.stop=1e9"], "experiment.stop"),
    "disturbance, stop = 1e9": ("ziemkiewicz_fig7a", ["experiment.stop=1e9"], "experiment.stop"),
    "free_period, 1e15 periods": ("ziemkiewicz_fig1", ["analysis.periods=1000000000000000"], "analysis.periods"),
    "steady_orbit, 1e7 periods": ("ziemkiewicz_fig3", ["analysis.periods=10000000"], "analysis.periods"),
    "step_accuracy, a tiny fixed step": ("ziemkiewicz_fig11", ['analysis.fixed_steps=["1e-12 s"]'],
                                         "analysis.fixed_steps"),
    "step_accuracy, a tiny paper step": ("ziemkiewicz_fig11", ['analysis.paper_steps=["1e-12 s"]'],
                                         "analysis.paper_steps"),
    "step_accuracy, 5000 runs": ("ziemkiewicz_fig11",
                                 ["analysis.rtols=[" + ",".join(f"{1e-6 * (1 + k / 1e4)!r}" for k in range(5000)) + "]"],
                                 "analysis.rtols"),
    "steady_state, max_periods = 1e15": ("ziemkiewicz_fig4a", ["analysis.max_periods=1000000000000000"],
                                         "analysis.max_periods"),
    "hoyng_stationary, measure_periods = 1e15": ("hoyng_fig3", ["analysis.measure_periods=1000000000000000"],
                                                 "analysis.measure_periods"),
    # Steady-state searches step a period per map evaluation in a Python loop.
    "steady_state, a step that makes each search take days": ("ziemkiewicz_fig4a", ["master.step=1e-7"],
                                                              "master.step"),
    "escapement_steady_state, the same": ("ziemkiewicz_fig2a", ["master.step=1e-7"], "master.step"),
    "weather_year, a check of 1e5 hours (1.3e10 steps)": ("air_weather_year", ["analysis.check_hours=100000"],
                                                          "analysis.check_hours"),
    "weather_year, a year's check at its step (2.5e10 steps)": ("air_weather_year", ["analysis.check_hours=8760"],
                                                                "analysis.check_hours"),
}


@pytest.mark.parametrize("case", list(KIND_CASES))
@pytest.mark.parametrize("command", ["validate", "run"])
def test_every_kind_refuses_an_unbounded_input_before_it_starts(capsys, tmp_path, case, command):
    scene, overrides, key = KIND_CASES[case]
    argv = [command, scene] + [a for o in overrides for a in ("--set", o)]
    argv += ["--out", tmp_path / "out", "--no-progress"] if command == "run" else []
    rc, _, err = run_cli(capsys, argv)
    assert_one_line_error(rc, err, f"{scene}.toml", key, code=2)
    assert not (tmp_path / "out").exists()


def test_a_run_that_records_little_but_steps_for_days_is_refused(capsys, tmp_path):
    f = _scene(tmp_path, stop=1e11, edit=lambda s: s.replace('ticks = "pendulum"', 'interval = "1e10 s"'))
    rc, _, err = run_cli(capsys, ["validate", f])
    assert_one_line_error(rc, err, str(f), "experiment.stop", "steps", code=2)


def test_every_kind_that_runs_over_a_span_declares_what_it_keeps():
    from clockwork.analyses.bounds import KEPT
    from clockwork.analyses.registry import ANALYSES

    spanless = {"time_series", "ticks",  # counted by clockwork.run.catalog
                "steady_state", "escapement_steady_state", "hoyng_stationary",  # end on their tolerance
                "barometric_coefficient", "thermal_coefficient", "weather_year"}
    assert set(ANALYSES) - spanless == set(KEPT)


@pytest.mark.parametrize("scene", ["hoyng_fig6", "hoyng_fig6_averaged", "ziemkiewicz_fig11", "ziemkiewicz_fig9a",
                                   "ziemkiewicz_fig10b", "ziemkiewicz_fig7a"])
def test_the_bundled_long_scenes_are_within_the_bounds(capsys, scene):
    rc, out, err = run_cli(capsys, ["validate", scene])
    assert rc == 0 and out.startswith("ok"), err


# --- rows at events count against the bound ---------------------------------------------


def test_input_events_count_against_the_recording_bound_at_validate(capsys, tmp_path):
    """Without record.interval every input event keeps a row off the grid:
    20,000 toggles of an input of an FMU with 1001 outputs keep 2.1e7
    values, past the bound, though the grid alone keeps 1e6 (accepted before)."""
    from cwtest import test_fmu
    from wide_fmu import wide_fmu

    fmu = wide_fmu(test_fmu("TestSink"), 1000, tmp_path / "wide.fmu")
    lines = ["time,u[1]"]
    for k in range(1, 20_001):
        t = k * 4.9e-5
        lines += [f"{t!r},{k % 2}", f"{t!r},{(k + 1) % 2}"]  # a time twice: a step, an input event
    (tmp_path / "in.csv").write_text("\n".join(lines) + "\n")
    # Kept in memory by clockwork.simulate (a run's series is streamed to disk: its size counts them too).
    from clockwork.errors import SceneError
    from clockwork.run.catalog import load_scene, series_size

    sets = ["experiment.stop=1", "master.step=0.001"]
    with pytest.raises(SceneError, match=r"2\.1e\+07 values"):
        load_scene(fmu, sets, tmp_path / "in.csv")
    assert load_scene(fmu, sets + ["record.interval=0.001"], tmp_path / "in.csv")  # events keep no row then
    assert series_size(load_scene(fmu, sets, tmp_path / "in.csv", streamed=True)) == (1001 + 20_000, 1 + 1001)


@pytest.mark.parametrize("engine", ["compiled", "python"])
def test_rows_at_located_events_count_against_the_bound_at_run_time(capsys, tmp_path, monkeypatch, engine):
    """Located events keep rows no check before the run can count: a series
    kept in memory (clockwork.simulate's, a sweep point's) stops at the
    bound and keeps what it recorded."""
    from clockwork.analyses import time_series
    from clockwork.errors import SimulationError
    from clockwork.run.catalog import load_scene

    # 2 s at 0.01 s: 201 grid rows of 2 columns (time, phi), 3 more at events; the bound lets 202 rows in.
    monkeypatch.setattr(time_series, "MAX_KEPT_VALUES", 404)
    f = _scene(tmp_path, stop=2.0, edit=lambda s: s.replace('ticks = "pendulum"', ""))
    with pytest.raises(SimulationError, match="recorded values") as e:
        time_series.time_series(load_scene(f, [f"master.engine={engine}"]), {})
    assert "record.interval" in str(e.value)
    assert 202 <= len(e.value.history["series"]["time"]) <= 210
    # written to disk as it goes, a run has no such bound
    rc, _, err = run_cli(capsys, ["run", f, "--out", tmp_path / "out", "--no-progress", "--no-plot",
                                  "--set", f"master.engine={engine}"])
    assert rc == 0, err
    assert len((tmp_path / "out" / "timeseries.csv").read_text().splitlines()) == 1 + 204

