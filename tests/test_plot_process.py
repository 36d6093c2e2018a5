"""The plot process (clockwork.results.plots.background).

A run forks a child that imports matplotlib while the points run and draws
the plots, several at once. It must draw exactly what this process would
draw, survive its own death (the plots are then drawn here, with one
warning), and never outlive or confuse an interrupted run. These run in
fresh interpreters: the test process itself has matplotlib loaded, where
the plots are drawn in-process.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from cwtest import CLOCK_SCENE, FMU_DIR, ROOT, assert_one_line_error, default_stop_signals, fmu_file

sys.path.insert(0, str(ROOT / "tools"))
from kill_sweep import descendants, running  # noqa: E402

# A sweep with five plots, more than there are cores: the plot process deals
# them round-robin to itself and its helpers. "boom" (raises) and "blank"
# (nothing to draw) are plot kinds the driver registers.
SCENE = CLOCK_SCENE.format(stop=3, sweep=textwrap.dedent("""\
    [sweep]
    axes = [{ parameter = "escapement.torque", values = ["0.3 N.cm", "0.4 N.cm", "0.5 N.cm"] }]
    [[plot]]
    kind = "sweep"
    x = "escapement.torque"
    y = "last_amplitude_deg"
    file = "a.png"
    [[plot]]
    kind = "boom"
    file = "b.png"
    [[plot]]
    kind = "sweep"
    x = "escapement.torque"
    y = ["ticks"]
    file = "c.png"
    [[plot]]
    kind = "blank"
    file = "d.png"
    [[plot]]
    kind = "sweep"
    x = "escapement.torque"
    y = "last_amplitude_deg"
    file = "e.png"
    """))

# Draws the scene's plots twice: by the plot process into DIR/forked, then in
# this process into DIR/here; prints both outcomes. SABOTAGE names which
# process of the plot process's family kills itself when it starts drawing.
DRIVER = textwrap.dedent("""\
    import json, os, signal, sys
    from pathlib import Path
    from clockwork.results.plots import Plotter, background, register, registry
    from clockwork.run.catalog import load_scene
    from clockwork.run.points import run_point

    @register("boom")
    def boom(scene, results, spec):
        raise ValueError("a broken plot kind")

    @register("blank")
    def blank(scene, results, spec):
        return None

    scene = load_scene(sys.argv[1])
    out = Path(sys.argv[2])
    main = os.getpid()
    sabotage = os.environ.get("SABOTAGE")
    draw = background.draw_plot

    def sabotaged(scene, results, out, k):
        child = os.getppid() == main
        if (sabotage == "child" and child) or (sabotage == "helper" and os.getpid() != main and not child):
            os.kill(os.getpid(), signal.SIGKILL)
        return draw(scene, results, out, k)

    background.draw_plot = sabotaged
    assert "matplotlib.figure" not in sys.modules
    (out / "forked").mkdir()
    with Plotter.start(scene) as plotter:  # first, as a run does: it imports matplotlib meanwhile
        forked_by = type(plotter).__name__
        results = [run_point(scene, p) for p in scene.points()]
        plotter.submit(results, out / "forked")
        forked = plotter.collect()
    (out / "here").mkdir()
    here = registry.make_plots(scene, results, out / "here")
    print(json.dumps({"by": forked_by, "forked": forked, "here": here}))
    """)


def _drive(tmp_path: Path, sabotage: str | None = None):
    scene = tmp_path / "plots.toml"
    scene.write_text(SCENE)
    driver = tmp_path / "driver.py"
    driver.write_text(DRIVER)
    env = dict(os.environ, CLOCKWORK_FMU_DIR=str(FMU_DIR), PYTHONPATH=str(ROOT), CLOCKWORK_CACHE="off")
    env.pop("SABOTAGE", None)
    if sabotage:
        env["SABOTAGE"] = sabotage
    r = subprocess.run([sys.executable, str(driver), str(scene), str(tmp_path)], env=env,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1]), r.stderr


@pytest.fixture(autouse=True)
def _fmus():
    fmu_file("Pendulum")


def _files(d: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(d.iterdir())}


def test_the_plot_process_draws_what_this_process_draws(tmp_path):
    got, err = _drive(tmp_path)
    assert got["by"] == "_PlotProcess"
    assert got["forked"] == got["here"]
    written, failed, empty, notes = got["forked"]
    assert written == ["a.png", "c.png", "e.png"]
    assert [f["file"] for f in failed] == ["b.png"] and "a broken plot kind" in failed[0]["error"]
    assert [e["file"] for e in empty] == ["d.png"]
    assert notes == []
    assert _files(tmp_path / "forked") == _files(tmp_path / "here")  # the same PNG bytes, nothing else
    assert err == ""


@pytest.mark.parametrize("who", ["child", "helper"])
def test_a_plot_process_that_dies_leaves_the_plots_to_this_process(tmp_path, who):
    got, err = _drive(tmp_path, sabotage=who)
    assert got["forked"] == got["here"]
    assert _files(tmp_path / "forked") == _files(tmp_path / "here")
    lines = err.strip().splitlines()
    if who == "child":
        assert len(lines) == 1 and "plot process ended without drawing (killed by SIGKILL)" in lines[0], err
    else:  # the child draws the helper's plots itself, quietly: nothing was lost
        assert err == ""


@pytest.mark.serial  # a SIGINT to the process group at a moment the run has reached
def test_an_interrupted_run_leaves_no_plot_process_and_one_line(tmp_path):
    """Ctrl-C at a terminal signals the whole process group: the run says
    "interrupted" once, the plot process says nothing, and nobody stays."""
    scene = tmp_path / "long.toml"
    scene.write_text(CLOCK_SCENE.format(stop=400, sweep=textwrap.dedent("""\
        [sweep]
        axes = [{ parameter = "escapement.torque", start = "0.3 N.cm", stop = "0.5 N.cm", num = 40 }]
        [[plot]]
        kind = "sweep"
        x = "escapement.torque"
        y = "last_amplitude_deg"
        """)))
    env = dict(os.environ, CLOCKWORK_FMU_DIR=str(FMU_DIR), PYTHONPATH=str(ROOT), CLOCKWORK_CACHE="off")
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "clockwork", "run", str(scene), "--out", str(out),
                             "--workers", "1", "--no-progress"], env=env, start_new_session=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=default_stop_signals)
    family: set[int] = set()
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            family |= descendants(proc.pid)
            if family and (out / "points").is_dir() and any((out / "points").glob("*.json")):
                break
            assert proc.poll() is None, proc.communicate()
            time.sleep(0.01)
        assert family, "no plot process was started"
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert err.strip().splitlines() == ["clockwork: error: interrupted"], err
    deadline = time.monotonic() + 10
    while any(running(p) for p in family) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not [p for p in family if running(p)], "a plot process outlived the interrupted run"
    assert not (out / "summary.json").exists() and not list(out.glob("*.png"))
    assert not [p for p in out.rglob("*") if p.name.endswith(".part") or p.name.startswith(".staging")]


def test_a_sweep_on_worker_processes_hands_its_plots_over(tmp_path):
    """Pool workers are forked after the plot process and hold copies of its
    pipes: the hand-over must not wait for them (messages carry their length)."""
    scene = tmp_path / "plots.toml"
    scene.write_text(SCENE.replace('kind = "boom"', 'kind = "sweep"\nx = "escapement.torque"\ny = "ticks"')
                     .replace('kind = "blank"', 'kind = "sweep"\nx = "escapement.torque"\ny = "ticks"'))
    env = dict(os.environ, CLOCKWORK_FMU_DIR=str(FMU_DIR), PYTHONPATH=str(ROOT), CLOCKWORK_CACHE="off")
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "clockwork", "run", str(scene), "--out", str(out), "--workers", "2",
                        "--no-progress"], env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stderr == "", r.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["files"] == ["sweep.csv", "a.png", "b.png", "c.png", "d.png", "e.png", "summary.json"]
    assert all((out / f).stat().st_size > 1000 for f in summary["files"] if f.endswith(".png"))


# `clockwork run` forks its plot process at the command's start, before numpy
# is imported (clockwork.cli._plot_process). The driver runs the command as
# the installed entry point does and records every process the CLI forks
# (pid, whether numpy was imported then); at exit (atexit: an interrupted run
# leaves by os._exit after the handlers) it prints each one's fate: "reaped"
# when the command waited for it, "running" or "zombie" otherwise. SABOTAGE:
# "kill" kills the early process before the run adopts it, "interrupt" sends
# the run SIGTERM at its first point.
EARLY_DRIVER = textwrap.dedent("""\
    import atexit, json, os, signal, sys
    from clockwork import cli

    forked = []
    fork = cli.fork_child

    def recording(body):
        child = fork(body)
        forked.append((child.pid, "numpy" in sys.modules))
        return child

    cli.fork_child = recording
    run = cli.cmd_run

    def sabotaged(args):
        from clockwork.results.plots import background
        background.fork_child = recording  # a plot process forked later than the early one: counted too
        if os.environ.get("SABOTAGE") == "kill":
            os.kill(forked[0][0], signal.SIGKILL)
        if os.environ.get("SABOTAGE") == "interrupt":
            from clockwork.run import scene_run
            point = scene_run.run_point
            def interrupted(*a, **k):
                os.kill(os.getpid(), signal.SIGTERM)
                return point(*a, **k)
            scene_run.run_point = interrupted
        return run(args)

    cli.cmd_run = sabotaged
    body = cli._plot_process_body

    def watched(*a):  # in the early process: what it asked of the scene it was sent, and whether it
        # imported matplotlib lean (registry._lean_artists), into $WATCH
        if not os.environ.get("WATCH"):
            return body(*a)
        from clockwork.results.plots import background
        asked, get = [], background._SceneOnDemand.__getattr__

        def asking(self, name):
            if not name.startswith("_"):  # pickle's probes
                asked.append(name)
            return get(self, name)

        background._SceneOnDemand.__getattr__ = asking
        try:
            body(*a)
        finally:
            lines = sys.modules.get("matplotlib.lines")
            lean = lines is not None and lines.Line2D.set.__doc__ is None
            with open(os.environ["WATCH"], "w") as f:
                json.dump({"asked": asked, "lean": lean, "fmpy": "fmpy" in sys.modules}, f)

    cli._plot_process_body = watched

    def fate(pid):
        try:
            got, status = os.waitpid(pid, os.WNOHANG)
        except ChildProcessError:
            return "reaped"
        return "running" if got == 0 else "zombie"

    @atexit.register
    def report():
        print(json.dumps([[pid, numpy, fate(pid)] for pid, numpy in forked]), flush=True)
        for pid, _ in forked:  # whatever the command left, the test leaves nothing
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass

    sys.argv[0] = "clockwork"
    sys.exit(cli.console())
    """)

PLOTTED_SWEEP = textwrap.dedent("""\
    [sweep]
    axes = [{ parameter = "escapement.torque", values = ["0.3 N.cm", "0.4 N.cm"] }]
    [[plot]]
    kind = "sweep"
    x = "escapement.torque"
    y = "last_amplitude_deg"
    file = "a.png"
    """)


def _early(tmp_path: Path, *args: str, scene: str | None = PLOTTED_SWEEP, sabotage: str | None = None,
           watch: Path | None = None):
    """(exit code, forked [[pid, numpy imported, fate]], stdout lines, stderr) of
    `clockwork run SCENE --out DIR ARGS` through the driver; $TMPDIR is checked
    to be left empty."""
    (tmp_path / "tmp").mkdir()
    driver = tmp_path / "driver.py"
    driver.write_text(EARLY_DRIVER)
    path = tmp_path / "scene.toml"
    if scene is not None:
        path.write_text(CLOCK_SCENE.format(stop=0.5, sweep=scene))
    env = dict(os.environ, CLOCKWORK_FMU_DIR=str(FMU_DIR), PYTHONPATH=str(ROOT), CLOCKWORK_CACHE="off",
               TMPDIR=str(tmp_path / "tmp"))
    env.pop("SABOTAGE", None)
    env.pop("WATCH", None)
    if sabotage:
        env["SABOTAGE"] = sabotage
    if watch:
        env["WATCH"] = str(watch)
    r = subprocess.run([sys.executable, str(driver), "run", str(path), "--out", str(tmp_path / "out"),
                        "--no-progress", *args], env=env, capture_output=True, text=True, timeout=120,
                       preexec_fn=default_stop_signals)
    *out, fates = r.stdout.strip().splitlines()
    assert not list((tmp_path / "tmp").iterdir()), "a temporary file outlived the command"
    return r.returncode, json.loads(fates), out, r.stderr


def test_a_run_forks_its_plot_process_before_numpy_and_draws_there(tmp_path):
    code, forked, _, err = _early(tmp_path)
    assert code == 0 and err == "", err
    assert len(forked) == 1 and forked[0][1:] == [False, "reaped"], forked  # one process, forked before numpy
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["files"] == ["sweep.csv", "a.png", "summary.json"]
    assert (tmp_path / "out" / "a.png").stat().st_size > 1000


def test_the_early_plot_process_draws_result_columns_without_the_whole_scene(tmp_path):
    """A sweep's plot of result columns (Fig. 4(a)'s) reads the scene's
    plots, title and overrides only: its components (fmpy's model
    descriptions, the engine's classes) stay pickled, so that the process
    needs neither fmpy nor the engine before it draws. A plot of an axis
    "instance.variable" unpickles them (the tests above draw one)."""
    asked = tmp_path / "asked.json"
    columns = PLOTTED_SWEEP.replace('x = "escapement.torque"', 'x = "last_amplitude_deg"').replace(
        'y = "last_amplitude_deg"', 'y = ["ticks"]')
    code, forked, _, err = _early(tmp_path, "--workers", "1", scene=columns, watch=asked)
    assert code == 0 and err == "", err
    assert forked[0][1:] == [False, "reaped"], forked
    assert (tmp_path / "out" / "a.png").stat().st_size > 1000
    watched = json.loads(asked.read_text())
    assert watched["asked"] == [] and watched["lean"] is True  # matplotlib imported lean there
    (tmp_path / "axis").mkdir()
    code, _, _, err = _early(tmp_path / "axis", "--workers", "1", watch=asked)
    assert code == 0 and err == "", err
    assert "components" in json.loads(asked.read_text())["asked"]  # the axis's unit: the whole scene, unpickled there


def test_the_early_plot_process_draws_a_runs_default_plot_without_fmpy_or_the_scene(tmp_path, capsys):
    """A single run's default plot (kind outputs: units and types of the
    recorded columns, the one component's name) gets what it reads of the
    scene computed by the run (_SceneOnDemand.recorded_view): the plot
    process draws it without unpickling the scene (fmpy and the engine not needed), its
    time on the first run's path (benchmarks/bench_first_run.py), and the
    PNG is the one this process draws to the byte."""
    asked = tmp_path / "asked.json"
    code, forked, _, err = _early(tmp_path, scene="", watch=asked)
    assert code == 0 and err == "", err
    assert forked[0][1:] == [False, "reaped"], forked
    # nothing asked of the scene it was sent (fmpy may still come in while it waits: _import_while_waiting)
    watched = json.loads(asked.read_text())
    assert watched["asked"] == [] and watched["lean"] is True
    from cwtest import run_cli

    here = tmp_path / "here"
    rc, _, err = run_cli(capsys, ["run", tmp_path / "scene.toml", "--out", here, "--no-progress"])
    assert rc == 0, err
    assert (tmp_path / "out" / "outputs.png").read_bytes() == (here / "outputs.png").read_bytes()


@pytest.mark.parametrize("case", ["no plots", "--no-plot", "bad input", "missing scene", "--help"])
def test_an_early_plot_process_the_run_does_not_use_ends_without_a_trace(tmp_path, case):
    """Whatever the run turns out to be, the early process is reaped before
    the command ends, says nothing, and leaves the exit code alone."""
    scene, args = PLOTTED_SWEEP, ()
    if case == "no plots":  # a sweep without [[plot]] tables has none
        scene = PLOTTED_SWEEP.split("[[plot]]")[0]
    elif case == "--no-plot":
        args = ("--no-plot",)
    elif case == "bad input":
        scene = PLOTTED_SWEEP.replace('"0.3 N.cm"', '"0.3 furlongs"')
    elif case == "missing scene":
        scene = None
    elif case == "--help":
        args = ("--help",)
    code, forked, out, err = _early(tmp_path, *args, scene=scene)
    if case in ("no plots", "--no-plot"):
        assert code == 0 and err == "", err
        assert json.loads((tmp_path / "out" / "summary.json").read_text())["files"] == ["sweep.csv", "summary.json"]
    elif case == "--help":
        assert code == 0 and err == "" and any("usage: clockwork run" in line for line in out), (out, err)
    else:
        assert_one_line_error(code, err, "scene.toml")
    if case == "--no-plot":
        assert forked == []  # nothing to draw: nothing forked
    else:
        assert len(forked) == 1 and forked[0][1:] == [False, "reaped"], forked


def test_an_early_plot_process_killed_before_the_run_adopts_it_leaves_the_plots_here(tmp_path):
    code, forked, _, err = _early(tmp_path, sabotage="kill")
    assert code == 0, err
    assert err.strip().splitlines() == [
        "clockwork: warning: the plot process ended without drawing (killed by SIGKILL); drawing here"], err
    assert forked[0][1:] == [False, "reaped"]
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["files"] == ["sweep.csv", "a.png",
                                                                                   "summary.json"]


def test_an_interrupted_run_reaps_its_early_plot_process(tmp_path):
    code, forked, _, err = _early(tmp_path, "--workers", "1", sabotage="interrupt")
    assert code == 128 + signal.SIGTERM, err
    assert err.strip().splitlines() == ["clockwork: error: interrupted by SIGTERM"], err
    assert len(forked) == 1 and forked[0][1:] == [False, "reaped"], forked
    assert not (tmp_path / "out" / "summary.json").exists()


def test_a_saved_png_is_what_savefig_crops_to_the_tight_box(tmp_path):
    """registry.save finds the tight box itself (one layout of the figure,
    not two): the bytes must be savefig(bbox_inches="tight")'s, labels, a
    legend and text below the axes (the --set line) included."""
    import io

    from clockwork.results.plots.registry import PNG_DPI, save, subplots

    def figure():
        fig, ax = subplots(figsize=(6.4, 3.6))
        ax.plot([1, 2, 3], [1e-3, 5e-3, 2e-3], ".-", label="a long legend entry, E_T_s_per_day")
        ax.set_xlabel("amplitude_deg")
        ax.set_ylabel("torque_Nm (N.m)")
        ax.set_title("a title", fontsize=10)
        ax.legend(loc="best")
        fig.text(0.01, 0.0, "--set pendulum.Q=900  escapement.torque=0.4", fontsize=7, va="top")
        return fig

    save(figure(), tmp_path / "a.png")
    expected = io.BytesIO()
    figure().savefig(expected, format="png", dpi=PNG_DPI, bbox_inches="tight")
    assert (tmp_path / "a.png").read_bytes() == expected.getvalue()


# Draws one figure with many kinds of artist (lines, markers, a legend,
# patches, collections, an image, a colour bar, text, an arrow, mathtext)
# into argv[2], after matplotlib was imported lean (the plot process's way)
# or as a library user's program imports it; prints what Line2D.set says.
LEAN_DRIVER = textwrap.dedent("""\
    import json, sys
    from pathlib import Path
    import numpy as np
    from clockwork.results.plots import registry

    registry.load_matplotlib(lean=sys.argv[1] == "lean")
    from matplotlib.lines import Line2D

    fig, (a, b) = registry.subplots(1, 2, figsize=(8, 3))
    x = np.linspace(0.0, 6.0, 40)
    line, = a.plot(x, np.sin(x), "o-", ms=3, label="E_T_s_per_day")
    line.set(color="C3", linewidth=1.5, alpha=0.8)
    a.fill_between(x, np.sin(x) - 0.1, np.sin(x) + 0.1, alpha=0.3)
    a.bar([1, 2, 3], [0.2, -0.4, 0.6], width=0.3, label="bars")
    a.scatter(x[::5], np.cos(x[::5]), c=x[::5], s=12)
    a.errorbar([4, 5], [0.1, -0.1], yerr=0.05, fmt="s")
    a.annotate("$\\\\phi_r$ = 2 deg", xy=(3, 0), xytext=(4, 0.6), arrowprops={"arrowstyle": "->"})
    a.set_yscale("symlog", linthresh=0.1)
    a.legend(loc="best", fontsize=8)
    image = b.imshow(np.outer(np.sin(x), np.cos(x)), aspect="auto")
    fig.colorbar(image, ax=b)
    b.contour(np.outer(np.sin(x), np.cos(x)), levels=[-0.5, 0.0, 0.5], colors="k")
    b.set(xlabel="amplitude_deg", ylabel="torque_Nm (N.m)", title="a title")
    fig.text(0.01, 0.0, "--set pendulum.Q=900", fontsize=7, va="top")
    registry.save(fig, Path(sys.argv[2]))
    try:
        line.set(colour="red")
        error = None
    except AttributeError as e:
        error = str(e)
    print(json.dumps({"documented": Line2D.set.__doc__ is not None, "error": error,
                      "color": line.get_color(), "linewidth": line.get_linewidth()}))
    """)


def test_matplotlib_imported_lean_draws_the_same_bytes_and_set_works_as_before(tmp_path):
    """The plot process imports matplotlib without the generated signatures
    and docstrings of the artists' ``set`` methods (a third of its import
    time): the drawing is the same to the byte, ``set`` sets and refuses as
    before, and a program that imports clockwork as a library keeps
    matplotlib's docstrings."""
    driver = tmp_path / "lean.py"
    driver.write_text(LEAN_DRIVER)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    said = {}
    for how in ("lean", "full"):
        r = subprocess.run([sys.executable, str(driver), how, str(tmp_path / f"{how}.png")], env=env,
                           capture_output=True, text=True, timeout=120)
        assert r.returncode == 0 and r.stderr == "", r.stderr
        said[how] = json.loads(r.stdout.strip().splitlines()[-1])
    assert (tmp_path / "lean.png").read_bytes() == (tmp_path / "full.png").read_bytes()
    assert said["lean"]["documented"] is False and said["full"]["documented"] is True
    for how in ("lean", "full"):
        assert said[how]["color"] == "C3" and said[how]["linewidth"] == 1.5
        assert said[how]["error"] == "Line2D.set() got an unexpected keyword argument 'colour'"
