"""The default plot of a time series (kind `outputs`): grouped by unit onto
stacked axes, sizes apart split, Booleans and discrete signals as steps, at
most a screenful per page; and `clockwork plot RESULT_DIR` drawing a
finished run again from its files."""

from __future__ import annotations

import json

import numpy as np
import pytest

from clockwork.results.plots.outputs import MAX_AXES, MAX_LINES, Column, columns, draw_outputs, group
from cwtest import ROOT, assert_one_line_error, run_cli, test_fmu


def _col(name, unit, size, kind="real"):
    return Column(name, np.array([0.0, size]), unit, kind)


def test_outputs_group_by_unit_in_order_of_first_appearance():
    cols = [_col("w", "deg/s", 5000), _col("tau", "N.cm", 40), _col("i", "A", 2), _col("w2", "deg/s", 4000),
            _col("load", "N.cm", -30)]
    assert [[c.name for c in ax] for ax in group(cols)] == [["w", "w2"], ["tau", "load"], ["i"]]


def test_sizes_far_apart_in_one_unit_get_axes_of_their_own():
    cols = [_col("sensor", "A", 1e-3), _col("supply", "A", 10), _col("motor", "A", 2), _col("off", "A", 0.0)]
    assert [[c.name for c in ax] for ax in group(cols)] == [["supply", "motor"], ["sensor", "off"]]


def test_booleans_share_axes_and_no_axes_holds_too_many_lines():
    cols = [_col(f"y{k}", "m", 1.0) for k in range(MAX_LINES + 3)] + [_col("on", "", 1, "boolean"),
                                                                        _col("n", "", 1, "discrete")]
    axes = group(cols)
    assert [len(a) for a in axes] == [MAX_LINES, 3, 1, 1]
    assert [c.name for c in axes[2]] == ["on"] and [c.name for c in axes[3]] == ["n"]


def test_discrete_signals_are_steps_and_pages_hold_at_most_a_screenful():
    cols = [_col(f"y{k}", f"u{k}", 1.0, "discrete" if k % 2 else "real") for k in range(MAX_AXES + 2)]
    figures = draw_outputs([0.0, 1.0], cols, "many")
    assert len(figures) == 2 and [len(f.axes) for f in figures] == [MAX_AXES, 2]
    styles = [ax.get_lines()[0].get_drawstyle() for f in figures for ax in f.axes]
    assert styles == ["default", "steps-post"] * 4
    w, h = figures[0].get_size_inches() * 110
    assert w <= 1100 and h <= 1000  # pixels at the dpi plots are saved with
    assert all(ax.get_legend() is not None for f in figures for ax in f.axes)
    assert figures[0].axes[0].get_shared_x_axes().joined(figures[0].axes[0], figures[0].axes[-1])


def test_columns_take_units_types_and_display_units():
    series = {"time": [0.0, 1.0], "p.phi": [0.0, 1.0], "p.n": [0, 1], "p.s": ["a", "b"], "p.on": [0.0, 1.0]}
    info = {"p.phi": {"unit": "rad", "type": "Real", "variability": "continuous"},
            "p.n": {"unit": None, "type": "Integer", "variability": "discrete"},
            "p.s": {"unit": None, "type": "String", "variability": "discrete"},
            "p.on": {"unit": None, "type": "Boolean", "variability": "discrete"}}
    cols = columns(series, info, strip="p")
    assert [(c.name, c.unit, c.kind) for c in cols] == [("phi", "deg", "real"), ("n", "", "discrete"),
                                                         ("on", "", "boolean")]
    assert cols[0].values[1] == pytest.approx(180 / np.pi)
    assert [c.name for c in columns(series, info, ["p.p*"], patterns=True)] == ["p.phi"]
    assert columns(series, info, ["p.p*"]) == []  # patterns only where asked for


def test_a_scene_without_plots_gets_the_default_plot_in_pages(capsys, tmp_path):
    """A clock with a vibrating mechanism recording every output: more units than a page holds."""
    text = (ROOT / "scenarios" / "core_vibration.toml").read_text().split("[[plot]]")[0]
    text = text.replace('stop = "202 s"', 'stop = "1 s"')
    text = text.replace('outputs = ["pendulum.phi", "pendulum.w", "escapement.tau", "vibration.a2"]\n', "")
    assert "outputs =" not in text
    (tmp_path / "clock.toml").write_text(text)
    rc, out, err = run_cli(capsys, ["run", tmp_path / "clock.toml", "--out", tmp_path / "r", "--no-progress"])
    assert rc == 0, err
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    pages = [p for p in summary["files"] if p.startswith("outputs")]
    assert pages[:2] == ["outputs.png", "outputs_2.png"]
    assert all((tmp_path / "r" / p).stat().st_size > 10_000 for p in pages)


def test_clockwork_plot_redraws_a_run(capsys, tmp_path):
    rc, _, err = run_cli(capsys, ["run", test_fmu("TestStair"), "--out", tmp_path / "r", "--no-progress",
                                  "--set", "experiment.stop=3"])
    assert rc == 0, err
    png = tmp_path / "r" / "outputs.png"
    png.unlink()
    rc, out, err = run_cli(capsys, ["plot", tmp_path / "r"])
    assert rc == 0 and out.strip() == f"wrote {png}" and png.stat().st_size > 10_000, err
    rc, out, err = run_cli(capsys, ["plot", tmp_path / "r", "--only", "odd", "TestStair.c*", "--out",
                                    tmp_path / "few.png"])
    assert rc == 0 and out.strip() == f"wrote {tmp_path / 'few.png'}", err


def test_clockwork_plot_leaves_pages_it_did_not_write_with_a_note(capsys, tmp_path):
    """Only files this drawing wrote are touched (issue 37: `--out mine/holiday.png`
    deleted a mine/holiday_2.png): a page of an earlier drawing stays, said once."""
    rc, _, err = run_cli(capsys, ["run", test_fmu("TestStair"), "--out", tmp_path / "r", "--no-progress",
                                  "--set", "experiment.stop=1"])
    assert rc == 0, err
    (tmp_path / "r" / "outputs_2.png").write_bytes(b"an old page")
    (tmp_path / "r" / "outputs_x.png").write_bytes(b"not a page")
    rc, _, err = run_cli(capsys, ["plot", tmp_path / "r"])
    assert rc == 0 and err == f"clockwork: note: {tmp_path / 'r'}: outputs_2.png not written by this drawing: " \
        "left as they are\n", err
    assert (tmp_path / "r" / "outputs_2.png").read_bytes() == b"an old page"
    assert (tmp_path / "r" / "outputs_x.png").exists()


@pytest.mark.parametrize("make, args, needle", [
    (lambda d: None, [], "no such directory"),
    (lambda d: d.mkdir(), [], "no summary.json: expected the --out directory of a clockwork run"),
    (lambda d: (d.mkdir(), (d / "summary.json").write_text("{nan")), [], "not a summary clockwork wrote"),
    (lambda d: (d.mkdir(), (d / "summary.json").write_text("{}")), [], "no timeseries.csv"),
    (lambda d: (d.mkdir(), (d / "summary.json").write_text("{}"), (d / "timeseries.csv").write_text("time,a\n0,x\n")),
     [], "line 2, column 2 (a): expected a number, got 'x'"),
    (lambda d: (d.mkdir(), (d / "summary.json").write_text("{}"), (d / "timeseries.csv").write_text("time,a\n0,1\n1\n")),
     [], "line 3: 1 values for 2 columns"),
    (lambda d: (d.mkdir(), (d / "summary.json").write_text("{}"), (d / "timeseries.csv").write_text("a,time\n0,1\n")),
     [], "line 1: expected a header line starting with time"),
    (lambda d: (d.mkdir(), (d / "summary.json").write_text("{}"), (d / "timeseries.csv").write_text("time,a\n0,1\n")),
     ["--only", "b*"], "--only b*: no recorded number matches; the columns are a"),
    (lambda d: (d.mkdir(), (d / "summary.json").write_text("{}"), (d / "timeseries.csv").write_text("time,a\n0,1\n")),
     ["--out", "x.svg"], "expected a file name ending .png"),
])
def test_clockwork_plot_refuses_what_is_not_a_run_in_one_line(capsys, tmp_path, make, args, needle):
    d = tmp_path / "r"
    make(d)
    rc, _, err = run_cli(capsys, ["plot", d, *args])
    assert_one_line_error(rc, err, needle, code=2)
