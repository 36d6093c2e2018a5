"""A run that fails keeps its history.

When an output turns NaN (or an FMU fails) the run stops with one stderr
line and exit code 1, and the output directory gets, committed whole like
any result: the series up to the last good communication point
(timeseries.csv, the plots) and summary.json whose "result" says failed,
when, where and why. A failed sweep point keeps its partial series in its
points/ file, is listed in summary.json, and is neither cached nor reused.

The FMU is tests/data/fmi3/linear.c: from t >= t_nan on its y[0] is NaN; a
step that would end after t_fail returns fmi3Error.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from clockwork.engine.recording import Recorder
from clockwork.engine.settings import MasterSettings
from clockwork.engine.system import System
from clockwork.errors import SimulationError
from clockwork.results.outdir import OutputDir
from cwtest import assert_one_line_error, run_cli
from fmi3_linear import fmu  # noqa: F401 (the test FMU, a fixture)

ENGINES = ["python", "compiled"]
ROOT = Path(__file__).resolve().parents[1]


def scene(tmp_path, fmu, params="t_nan = 0.45", engine="auto", extra="", name="s.toml"):
    f = tmp_path / name
    f.write_text(f"""[scene]
title = "failing"
[components.a]
fmu = "{fmu}"
parameters = {{ u = [1.0, -2.0], {params} }}
[experiment]
stop = 1.0
[master]
step = 0.1
engine = "{engine}"
[record]
outputs = ["a.y", "a.x"]
[[plot]]
kind = "time_series"
y = ["a.y[0]", "a.x[2]"]
file = "y.png"
{extra}""")
    return f


def read_csv(path):
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return {h: [r[k] for r in rows[1:]] for k, h in enumerate(rows[0])}


@pytest.mark.parametrize("engine", ENGINES)
def test_the_engines_keep_the_points_before_a_nan_only(fmu, engine):
    """The recorder holds every point before the one where y[0] turned NaN,
    not that one (the compiled core records a point after its divergence
    check), on both engines alike."""
    with System({"a": (str(fmu), {"t_nan": 0.45})}, [], MasterSettings(step=0.1, engine=engine),
                record={"a": ["y"]}) as s:
        rec = Recorder(s.master, [("a", "y")])
        rec.start()
        with pytest.raises(SimulationError) as e:
            s.master.run_until(1.0, rec)
    assert (e.value.time, e.value.instance, e.value.variable) == (0.5, "a", "y[0]")
    assert e.value.last_point == 0.4
    assert rec.columns["time"] == [0.0, 0.1, 0.2, 0.30000000000000004, 0.4]
    assert all(x == x for x in rec.columns["a.y[0]"])  # no NaN


@pytest.mark.parametrize("engine", ENGINES)
def test_a_false_alarm_of_the_divergence_check_is_recorded(fmu, engine):
    """A sum of legal outputs above the limit (each below it) is no failure:
    every point is recorded, on both engines the same."""
    runs = {}
    for e in ("python", engine):
        with System({"a": (str(fmu), {})}, [], MasterSettings(step=0.1, engine=e, divergence_limit=2.5),
                    record={"a": ["y", "x"]}) as s:
            rec = Recorder(s.master, [("a", "y"), ("a", "x")])
            rec.start()
            s.master.run_until(1.0, rec)
        runs[e] = rec.columns
    assert len(runs[engine]["time"]) == 11 and sum(v[0] for k, v in runs[engine].items() if k != "time") > 2.5
    assert runs[engine] == runs["python"]


def test_a_run_that_turns_nan_keeps_its_series_and_says_failed(capsys, tmp_path, fmu):
    """Exit 1 and one line; the series up to t = 0.4 s (the last good point),
    the plot, and summary.json saying when, where and why; the same bits on
    both engines."""
    csvs = {}
    for engine in ENGINES:
        out = tmp_path / engine
        rc, stdout, err = run_cli(capsys, ["run", scene(tmp_path, fmu, engine=engine), "--out", out,
                                           "--no-progress"])
        assert_one_line_error(rc, err, "a.y[0] = nan is not finite at t = 0.5 s", str(out), code=1)
        summary = json.loads((out / "summary.json").read_text())
        failed = summary["result"]["failed"]
        assert failed == {"time_s": 0.5, "last_point_s": 0.4, "instance": "a", "variable": "y[0]",
                          "message": "a.y[0] = nan is not finite at t = 0.5 s", "engine": engine}
        assert summary["files"] == ["timeseries.csv", "y.png", "summary.json"]
        assert (out / "y.png").stat().st_size > 1000 and not summary.get("plots_failed")
        csvs[engine] = read_csv(out / "timeseries.csv")
        assert csvs[engine]["time"] == ["0.0", "0.1", "0.2", "0.30000000000000004", "0.4"]
    assert csvs["python"] == csvs["compiled"]


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("t_nan, when, rows", [
    ("0.0", "0.0", []),  # at the start: no point is legal, and the time is the start's
    ("0.05", "0.1", ["0.0"]),  # within the first step: the start is kept
])
@pytest.mark.parametrize("alone", [False, True])
def test_a_nan_at_the_start_or_the_first_step_keeps_legal_numbers_only(capsys, tmp_path, fmu, engine, t_nan,
                                                                         when, rows, alone):
    """The history holds no NaN and the line gives the time of the point
    that failed, on both engines, for a scene and for the FMU alone."""
    out = tmp_path / "out"
    if alone:
        args = ["run", fmu, "--set", f"t_nan={t_nan}", "--set", "experiment.stop=1", "--set", "master.step=0.1",
                "--set", f"master.engine={engine}"]
    else:
        args = ["run", scene(tmp_path, fmu, f"t_nan = {t_nan}", engine)]
    rc, _, err = run_cli(capsys, [*args, "--out", out, "--no-progress"])
    assert_one_line_error(rc, err, f"y[0] = nan is not finite at t = {when} s", code=1)
    summary = json.loads((out / "summary.json").read_text())
    failed = summary["result"]["failed"]
    assert failed["time_s"] == float(when) and failed["variable"] == "y[0]"
    assert failed["last_point_s"] == (float(rows[-1]) if rows else None)
    if (out / "timeseries.csv").exists():
        table = read_csv(out / "timeseries.csv")
        assert table["time"] == rows
        assert not any(v.lower() in ("nan", "inf", "-inf") for col in table.values() for v in col)
    else:
        assert rows == [] and "timeseries.csv" not in summary["files"]


@pytest.mark.parametrize("engine", ENGINES)
def test_an_fmu_that_fails_keeps_the_series_until_its_failed_step(capsys, tmp_path, fmu, engine):
    out = tmp_path / "out"
    rc, _, err = run_cli(capsys, ["run", scene(tmp_path, fmu, "t_fail = 0.35", engine), "--out", out,
                                  "--no-progress"])
    assert_one_line_error(rc, err, "fmi3DoStep", "the model fails after t_fail = 0.34999999999999998 s",
                          code=1)
    failed = json.loads((out / "summary.json").read_text())["result"]["failed"]
    assert failed["time_s"] == failed["last_point_s"] == 0.30000000000000004 and failed["instance"] == "a"
    assert "the model fails after t_fail" in failed["message"]
    assert read_csv(out / "timeseries.csv")["time"][-1] == "0.30000000000000004"


def test_a_failed_run_replaces_an_earlier_result_whole(capsys, tmp_path, fmu):
    """The earlier result's files go (an extra plot too): the directory holds the failed run's result alone."""
    out = tmp_path / "out"
    good = scene(tmp_path, fmu, "t_nan = 5.0", extra='[[plot]]\nkind = "time_series"\nfile = "extra.png"\n',
                 name="good.toml")
    rc, _, err = run_cli(capsys, ["run", good, "--out", out, "--no-progress"])
    assert rc == 0, err
    assert (out / "extra.png").exists() and len(read_csv(out / "timeseries.csv")["time"]) == 11
    rc, _, err = run_cli(capsys, ["run", scene(tmp_path, fmu), "--out", out, "--no-progress"])
    assert rc == 1, err
    summary = json.loads((out / "summary.json").read_text())
    assert sorted(p.name for p in out.iterdir()) == sorted(summary["files"])
    assert len(read_csv(out / "timeseries.csv")["time"]) == 5


def test_a_sweep_keeps_the_other_points_and_caches_no_failed_one(capsys, tmp_path, fmu, monkeypatch):
    cache = tmp_path / "cache"
    monkeypatch.setenv("CLOCKWORK_CACHE", str(cache))
    f = scene(tmp_path, fmu, "t_fail = 9.0", extra='[sweep]\naxes = [ { parameter = "a.t_nan", '
                                                 'values = [0.45, 5.0] } ]\n')
    f.write_text(f.read_text().replace('[[plot]]\nkind = "time_series"\ny = ["a.y[0]", "a.x[2]"]\nfile = "y.png"\n',
                                       '[[plot]]\nkind = "sweep"\nx = "a.t_nan"\ny = ["t_end_s"]\n'))
    out = tmp_path / "out"
    for rerun in (False, True):
        rc, stdout, err = run_cli(capsys, ["run", f, "--out", out, "--no-progress"])
        assert_one_line_error(rc, err, "1 of 2 sweep points failed", code=1)
        summary = json.loads((out / "summary.json").read_text())
        assert summary["points_failed"] == 1 and summary["points_reused"] == int(rerun)
        bad = next(p for p in summary["points"] if p["point"]["a.t_nan"] == 0.45)
        assert bad["failed"]["time_s"] == 0.5 and bad["failed"]["variable"] == "y[0]" and "t_end_s" not in bad
        good = next(p for p in summary["points"] if p["point"]["a.t_nan"] == 5.0)
        assert good["t_end_s"] == 1.0 and "failed" not in good
        stored = [json.loads(p.read_text()) for p in (out / "points").glob("*.json")]
        failed = next(p for p in stored if "error" in p)
        assert "result" not in failed and failed["series"]["time"][-1] == 0.4
        cached = [json.loads(p.read_text()) for p in cache.glob("*/*.json")]
        assert len(cached) == 1 and "error" not in cached[0]


def test_the_python_api_gets_the_error_with_the_summary_and_the_history(tmp_path, fmu):
    from clockwork.run import load_scene, run_scene

    with pytest.raises(SimulationError) as e:
        run_scene(load_scene(scene(tmp_path, fmu)), tmp_path / "out", progress=False)
    assert e.value.summary["result"]["failed"]["time_s"] == 0.5
    assert e.value.history["series"]["time"][-1] == 0.4 and e.value.last_point == 0.4


_KILLER = textwrap.dedent("""
    import sys
    sys.path.insert(0, {root!r}); sys.path.insert(0, {tests!r})
    from test_commit import kill_at
    from clockwork.results import outdir
    from clockwork.run import load_scene, run_scene
    commit = outdir.OutputDir.commit
    def killing_commit(self):
        kill_at(int(sys.argv[3]))
        commit(self)
    outdir.OutputDir.commit = killing_commit
    try:
        run_scene(load_scene(sys.argv[1]), sys.argv[2], progress=False)
    except Exception as e:
        print(type(e).__name__, e)
        sys.exit(1)
""")


def _commit_calls(tmp_path, monkeypatch, good, bad) -> int:
    """How many file-system calls the failed run's commit makes (as the killer counts them)."""
    from clockwork.results import outdir
    from clockwork.run import load_scene, run_scene
    from test_commit import STEP_CALLS

    d = tmp_path / "count"
    run_scene(load_scene(good), d, progress=False)
    counted = [0]
    commit = outdir.OutputDir.commit

    def counting_commit(self):
        for name in STEP_CALLS:
            real = getattr(os, name)

            def call(*a, real=real, **kw):
                counted[0] += 1
                return real(*a, **kw)
            monkeypatch.setattr(os, name, call)
        commit(self)
    monkeypatch.setattr(outdir.OutputDir, "commit", counting_commit)
    with pytest.raises(SimulationError):
        run_scene(load_scene(bad), d, progress=False)
    monkeypatch.undo()
    return counted[0]


def test_a_kill_while_a_failed_run_commits_leaves_old_or_new(capsys, tmp_path, fmu, monkeypatch):
    """SIGKILL at the first call of the commit, in its middle, at its last
    call, and not at all: the next run finds the earlier result or the
    failed run's, never a mix (tests/test_commit.py kills at every call)."""
    monkeypatch.setenv("CLOCKWORK_CACHE", "off")
    good = scene(tmp_path, fmu, "t_nan = 5.0", extra='[[plot]]\nkind = "time_series"\nfile = "extra.png"\n',
                 name="good.toml")
    bad = scene(tmp_path, fmu)
    total = _commit_calls(tmp_path, monkeypatch, good, bad)
    assert total >= 8
    script = tmp_path / "killer.py"
    script.write_text(_KILLER.format(root=str(ROOT), tests=str(ROOT / "tests")))
    template = tmp_path / "template"
    rc, _, err = run_cli(capsys, ["run", good, "--out", template, "--no-progress"])
    assert rc == 0, err
    old = {p.name: p.read_bytes() for p in template.iterdir() if p.is_file()}
    outcomes = []
    for k in (1, total // 2, total, total + 1):
        d = tmp_path / f"k{k}"
        shutil.copytree(template, d)
        r = subprocess.run([sys.executable, str(script), str(bad), str(d), str(k)], capture_output=True,
                           text=True, env=dict(os.environ))
        killed = r.returncode == -signal.SIGKILL
        assert killed == (k <= total) and (killed or r.returncode == 1), (k, r.returncode, r.stderr)
        with OutputDir(d):  # as the next run opens it: a cut-short commit is finished or undone
            pass
        seen = {p.name: p.read_bytes() for p in d.iterdir() if p.is_file()}
        summary = json.loads(seen["summary.json"])
        if "failed" in summary.get("result", {}):
            assert sorted(seen) == sorted(summary["files"]) and b"extra.png" not in seen["summary.json"], k
            outcomes.append("new")
        else:
            assert seen == old, k
            outcomes.append("old")
    assert outcomes[0] == "old" and outcomes[-1] == "new"
    assert outcomes == sorted(outcomes, key=lambda o: o == "new")


@pytest.mark.parametrize("engine", ["python", "compiled"])
def test_the_divergence_limit_is_a_scene_key(tmp_path, capsys, engine):
    """master.divergence_limit, a MasterSettings field, was refused as an
    unknown key in a scene and by --set: now it is one, checked once, and
    reaches both engines."""
    import json

    from cwtest import CLOCK_SCENE, fmu_file, run_cli

    fmu_file("Pendulum")
    scene = tmp_path / "clock.toml"
    scene.write_text(CLOCK_SCENE.format(stop=0.3, sweep="").replace("[master]", "[master]\ndivergence_limit = 0.5"))
    rc, _, err = run_cli(capsys, ["run", scene, "--out", tmp_path / "low", "--no-plot", "--no-progress",
                                  "--set", f"master.engine={engine}"])
    assert rc == 1 and "exceeds the divergence limit 0.5" in err, err
    assert json.loads((tmp_path / "low" / "summary.json").read_text())["result"]["failed"]
    rc, _, err = run_cli(capsys, ["run", scene, "--out", tmp_path / "high", "--no-plot", "--no-progress",
                                  "--set", f"master.engine={engine}", "--set", "master.divergence_limit=1e12"])
    assert rc == 0, err
    for bad in ("0", "-1", "inf", '"big"'):
        rc, _, err = run_cli(capsys, ["validate", scene, "--set", f"master.divergence_limit={bad}"])
        assert rc == 2 and "master.divergence_limit" in err and len(err.strip().splitlines()) == 1, err
