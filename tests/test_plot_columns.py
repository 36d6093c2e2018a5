"""Every plot kind's columns are checked: a column that does not exist is
refused (exit 2, the plot's key in the line), never drawn as an empty plot.
Every analysis kind declares its result and series columns
(tests/test_result_columns.py holds them to the code), so a sweep axis
("instance.variable"), a result column and a series column are checked
when the scene is loaded, for every plot kind and analysis kind. A column
that is declared but that no point has (it exists only in some runs), and
the columns of a kind registered without a declaration, are refused as
soon as the points are computed, before anything is written (the points
are kept, so the corrected rerun is free).
"""

from __future__ import annotations

import json

import pytest

from cwtest import CLOCK_SCENE, FMU_DIR, assert_one_line_error, fmu_file, run_cli
from clockwork.run import load_scene
from clockwork.results.plots.registry import PLOT_COLUMNS

SWEEP = '\n[sweep]\naxes = [ { parameter = "escapement.torque", values = ["0.4 N.cm", "0.5 N.cm"] } ]\n'


@pytest.fixture(autouse=True)
def _env(monkeypatch, tmp_path):
    fmu_file("Pendulum")
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))
    monkeypatch.setenv("CLOCKWORK_CACHE", str(tmp_path / "cache"))


def _scene(tmp_path, plot: str, sweep: str = SWEEP):
    f = tmp_path / "s.toml"
    f.write_text(CLOCK_SCENE.format(stop=0.5, sweep=sweep + "\n[[plot]]\n" + plot + "\n"))
    return f


# (plot table, key in the error): a time_series scene, whose kind declares its result columns
BAD = {
    "sweep y": ('kind = "sweep"\nx = "escapement.torque"\ny = "no_such_column"', "plot[0].y"),
    "sweep y among good ones": ('kind = "sweep"\nx = "escapement.torque"\ny = ["t_end_s", "t_ends"]', "plot[0].y"),
    "sweep x result column": ('kind = "sweep"\nx = "amplitude"\ny = "t_end_s"', "plot[0].x"),
    "sweep x axis typo": ('kind = "sweep"\nx = "escapement.torqe"\ny = "t_end_s"', "plot[0].x"),
    "sweep default columns": ('kind = "sweep"\nx = "escapement.torque"', "plot[0].y"),
    "rate_errors y": ('kind = "rate_errors"\ny = ["E_X"]', "plot[0].y"),
    "contour z": ('kind = "contour"\nx = "escapement.torque"\ny = "escapement.torque"\nz = "nope"', "plot[0].z"),
    "curves group axis": ('kind = "curves"\nx = "t_end_s"\ny = ["t_end_s"]\ngroup = ["pendulum.Qx"]', "plot[0].group"),
    "hoyng_comparison theory": ('kind = "hoyng_comparison"\nx = "t_end_s"\ntheory = "nope"', "plot[0].theory"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_a_plot_of_a_missing_column_is_refused(capsys, tmp_path, case):
    plot, key = BAD[case]
    f = _scene(tmp_path, plot)
    rc, _, err = run_cli(capsys, ["validate", f])
    assert_one_line_error(rc, err, str(f), key, code=2)
    out = tmp_path / "out"
    rc, _, err = run_cli(capsys, ["run", f, "--out", out, "--no-progress", "--workers", "1"])
    assert_one_line_error(rc, err, str(f), key, code=2)
    assert not (out / "summary.json").exists() and not list(out.glob("*.png")) and not list(out.glob("*.csv"))


@pytest.fixture
def undeclared_kind():
    """An analysis kind that does not declare its result columns: checked after the points."""
    from clockwork.analyses.registry import ANALYSES, ANALYSIS_KEYS, RESULT_COLUMNS, _ANALYSIS_CONVERT, register

    register("columns_test")(lambda scene, point, progress=False: {"kind": "x", "result": {"value": 1.0}})
    yield "columns_test"
    for table in (ANALYSES, ANALYSIS_KEYS, RESULT_COLUMNS, _ANALYSIS_CONVERT):
        table.pop("columns_test", None)


@pytest.mark.parametrize("plot, key", [('kind = "sweep"\nx = "escapement.torque"\ny = "valu"', "plot[0].y"),
                                       ('kind = "sweep"\nx = "vale"\ny = "value"', "plot[0].x")])
def test_a_column_of_an_undeclared_kind_is_refused_after_the_points(capsys, tmp_path, undeclared_kind, plot, key):
    f = _scene(tmp_path, plot)
    f.write_text(f.read_text().replace('kind = "time_series"', f'kind = "{undeclared_kind}"'))
    rc, out, err = run_cli(capsys, ["validate", f])
    assert rc == 0, err
    out_dir = tmp_path / "out"
    rc, _, err = run_cli(capsys, ["run", f, "--out", out_dir, "--no-progress", "--workers", "1"])
    assert_one_line_error(rc, err, str(f), key, "no point has", code=2)
    assert not (out_dir / "summary.json").exists() and not list(out_dir.glob("*.png"))
    assert len(list((out_dir / "points").glob("*.json"))) == 2  # kept: the corrected scene reuses them
    f.write_text(f.read_text().replace('"valu"', '"value"').replace('"vale"', '"escapement.torque"'))
    rc, _, err = run_cli(capsys, ["run", f, "--out", out_dir, "--no-progress", "--workers", "1"])
    assert rc == 0, err
    assert json.loads((out_dir / "summary.json").read_text())["points_reused"] == 2


def test_phase_space_of_a_series_column_that_is_not_there(capsys, tmp_path):
    f = _scene(tmp_path, 'kind = "phase_space"\nx = "pendulum.phi"\ny = "pendulum.w"', sweep="")
    for argv in (["validate", f], ["run", f, "--out", tmp_path / "out", "--no-progress"]):
        rc, _, err = run_cli(capsys, argv)
        assert_one_line_error(rc, err, str(f), "plot[0].y", "pendulum.w", code=2)
    assert not (tmp_path / "out").exists()


def test_a_declared_column_that_no_point_has_is_refused_after_the_points(capsys, tmp_path):
    """mean_period_s is a time_series column only with record.ticks: this scene records none."""
    f = _scene(tmp_path, 'kind = "sweep"\nx = "escapement.torque"\ny = "mean_period_s"')
    f.write_text(f.read_text().replace('ticks = "pendulum"\n', ""))
    assert "ticks" not in f.read_text()
    rc, _, err = run_cli(capsys, ["validate", f])
    assert rc == 0, err
    out = tmp_path / "out"
    rc, _, err = run_cli(capsys, ["run", f, "--out", out, "--no-progress", "--workers", "1"])
    assert_one_line_error(rc, err, str(f), "plot[0].y", "mean_period_s", "no point has", code=2)
    assert not (out / "summary.json").exists() and len(list((out / "points").glob("*.json"))) == 2


def test_a_correct_sweep_plot_is_drawn(capsys, tmp_path):
    f = _scene(tmp_path, 'kind = "sweep"\nx = "escapement.torque"\ny = "t_end_s"\nfile = "ok.png"')
    rc, _, err = run_cli(capsys, ["run", f, "--out", tmp_path / "out", "--no-progress", "--workers", "1"])
    assert rc == 0, err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert "ok.png" in summary["files"] and "plots_not_drawn" not in summary


def test_every_plot_kind_that_names_columns_declares_them():
    """The kinds whose table takes x, y, z, group, theory or dashed keys say which are columns."""
    from clockwork.results.plots.registry import PLOT_COLUMNS, PLOT_KEYS

    naming = {"x", "y", "z", "group", "theory", "dashed", "dashed_if"}
    for kind, keys in PLOT_KEYS.items():
        assert set(keys) & naming <= set(PLOT_COLUMNS[kind][0]), kind


@pytest.mark.parametrize("y, ok", [("E_T_s_per_dya", False), ("E_T_s_per_day", True), ("amplitude_deg", True)])
def test_a_steady_state_scene_is_checked_at_validation(capsys, tmp_path, y, ok):
    f = _scene(tmp_path, f'kind = "sweep"\nx = "escapement.torque"\ny = "{y}"')
    f.write_text(f.read_text().replace('kind = "time_series"', 'kind = "steady_state"'))
    rc, _, err = run_cli(capsys, ["validate", f])
    if ok:
        assert rc == 0, err
    else:
        assert_one_line_error(rc, err, str(f), "plot[0].y", "did you mean E_T_s_per_day?", code=2)


def _bundled_scene_of_each_kind() -> dict[str, str]:
    """analysis kind -> a bundled scene of that kind (ticks: core_grasshopper, made a ticks run)."""
    import tomllib

    from clockwork.paths import scenarios_dir

    out = {}
    for f in sorted(scenarios_dir().glob("*.toml")):
        out.setdefault(tomllib.loads(f.read_text()).get("analysis", {}).get("kind", "time_series"), f.stem)
    out["ticks"] = "ticks"  # none bundled: _with_plot makes one
    return out


KIND_SCENES = _bundled_scene_of_each_kind()
# Plot kinds of sweep rows, and the column key each is tried with (the others in the next test).
ROW_PLOTS = {"sweep": "y", "rate_errors": "dashed", "contour": "z", "curves": "y", "hoyng_comparison": "theory"}


def _with_plot(tmp_path, kind: str, plot: dict):
    """The bundled scene of analysis `kind` with one more plot: (file, that plot's index)."""
    import tomllib

    from clockwork.paths import scenarios_dir

    if kind == "ticks":  # the test scene: core_grasshopper's plots of series a ticks run has not
        text = CLOCK_SCENE.format(stop=0.5, sweep="").replace('kind = "time_series"', 'kind = "ticks"')
        assert 'kind = "ticks"' in text
    else:
        text = (scenarios_dir() / f"{KIND_SCENES[kind]}.toml").read_text()
    n = len(tomllib.loads(text).get("plot", []))
    f = tmp_path / "s.toml"
    f.write_text(text + "\n[[plot]]\n" + "".join(f"{k} = {json.dumps(v)}\n" for k, v in plot.items()))
    return f, n


def test_every_analysis_kind_has_a_bundled_scene():
    from clockwork.analyses.registry import ANALYSES

    assert set(ANALYSES) <= set(KIND_SCENES)


@pytest.mark.parametrize("analysis", sorted(KIND_SCENES))
@pytest.mark.parametrize("plot_kind", list(ROW_PLOTS))
def test_a_missing_column_of_every_plot_kind_and_analysis_kind_is_refused_at_validation(
        capsys, tmp_path, monkeypatch, plot_kind, analysis):
    from clockwork.analyses.registry import result_columns

    fmu_file("Air")
    f, _ = _with_plot(tmp_path, analysis, {"kind": "sweep", "x": "no_such_column"})
    f.write_text(f.read_text().rsplit("[[plot]]", 1)[0])
    good = min(result_columns(load_scene(f)))  # a column the kind declares for this scene
    key = ROW_PLOTS[plot_kind]
    plot = {"kind": plot_kind, **{k: good for k in PLOT_COLUMNS[plot_kind][0]}, key: "no_such_column"}
    f, n = _with_plot(tmp_path, analysis, plot)
    rc, _, err = run_cli(capsys, ["validate", f])
    assert_one_line_error(rc, err, str(f), f"plot[{n}].{key}", f"not a column of {analysis} results", code=2)


@pytest.mark.parametrize("plot_kind, key", [(p, k) for p in ROW_PLOTS for k in ("x", "y", "z", "group", "theory",
                                                                              "dashed", "dashed_if")
                                            if k in PLOT_COLUMNS[p][0]])
def test_every_column_key_of_a_row_plot_is_checked_at_validation(capsys, tmp_path, plot_kind, key):
    """Each key naming columns, on an escapement_steady_state scene, with a typo: the nearest name is given."""
    plot = {"kind": plot_kind, "x": "amplitude_deg", "y": ["E_T_s_per_day"] if plot_kind != "contour" else "period_s",
            "z": "E_T_s_per_day", "group": ["E_C_s_per_day"], "theory": "E_E_s_per_day", "dashed": ["E_E_s_per_day"],
            "dashed_if": "stalled"}
    plot = {k: v for k, v in plot.items() if k == "kind" or k in PLOT_COLUMNS[plot_kind][0]}
    if plot_kind == "hoyng_comparison":
        plot["group"] = "E_C_s_per_day"  # one column there
    plot[key] = "E_T_s_per_dya"
    f, n = _with_plot(tmp_path, "escapement_steady_state", plot)
    rc, _, err = run_cli(capsys, ["validate", f])
    assert_one_line_error(rc, err, str(f), f"plot[{n}].{key}", "did you mean E_T_s_per_day?", code=2)


SERIES_PLOTS = [k for k, (keys, source) in PLOT_COLUMNS.items() if source == "series" and keys]


def test_the_series_plot_kinds_are_known():
    assert set(SERIES_PLOTS) == {"time_series", "phase_portrait", "phase_space", "outputs"}


@pytest.mark.parametrize("analysis", sorted(KIND_SCENES))
@pytest.mark.parametrize("plot_kind", SERIES_PLOTS)
def test_a_missing_series_column_of_every_analysis_kind_is_refused_at_validation(capsys, tmp_path, plot_kind, analysis):
    """y names no series column; where the kind has a series, x naming one of them passes."""
    from clockwork.analyses.registry import series_columns

    fmu_file("Air")
    f, _ = _with_plot(tmp_path, analysis, {"kind": "sweep", "x": "no_such_column"})
    f.write_text(f.read_text().rsplit("[[plot]]", 1)[0])
    series = sorted(series_columns(load_scene(f)))
    plot = {"kind": plot_kind, "x": series[0] if series else "time", "y": "no_such_column"}
    takes_x = "x" in PLOT_COLUMNS[plot_kind][0]
    f, n = _with_plot(tmp_path, analysis, plot if takes_x else {"kind": plot_kind, "y": "no_such_column"})
    rc, _, err = run_cli(capsys, ["validate", f])
    key = f"plot[{n}].y" if series or not takes_x else f"plot[{n}].x"
    if analysis == "time_series" and plot_kind != "phase_space":  # the scene's own check, with its advice
        assert_one_line_error(rc, err, str(f), key, "is not recorded", "record.outputs", code=2)
    else:
        assert_one_line_error(rc, err, str(f), key, f"not a column of {analysis} series",
                              "expected one of" if series else "has no series", code=2)
