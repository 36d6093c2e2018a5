"""The clockwork command: validate, list, info, run's plumbing, and one-line errors."""

import os
import re
import sys
import types
import zipfile
from pathlib import Path

import pytest

from cwtest import FMU_DIR, assert_one_line_error, fmu_file, run_cli
from clockwork.errors import SimulationError

DATA = Path(__file__).resolve().parent / "data" / "scenes"
GOOD = DATA / "good.toml"
TINY = '[scene]\ntitle = "tiny"\n[components.pendulum]\nfmu = "{fmu}"\n[experiment]\nstop = 0.2\n' \
       '[master]\nstep = 0.01\n'


@pytest.fixture(autouse=True)
def _fmu_dir(monkeypatch):
    fmu_file("Pendulum")
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))


run = run_cli


def test_validate_ok(capsys):
    rc, out, err = run(capsys, ["validate", GOOD])
    assert rc == 0 and err == ""
    assert out == "ok: Two pendulums (2 components, 0 connections, 6 sweep points)\n"


def test_validate_with_set(capsys):
    rc, out, _ = run(capsys, ["validate", GOOD, "--set", "pendulum.Q=500", "--set", "master.step=0.02"])
    assert rc == 0 and out.startswith("ok: ")
    assert out.rstrip().endswith("with --set pendulum.Q=500 master.step=0.02)")  # the ok line names what was set


def test_list_marks_broken_scenes(capsys):
    rc, out, err = run(capsys, ["list", DATA])
    assert rc == 1  # some fixtures are broken on purpose
    lines = out.splitlines()
    assert len(lines) == len(list(DATA.glob("*.toml")))
    good = [ln for ln in lines if ln.startswith("good.toml")]
    assert len(good) == 1 and "Two pendulums" in good[0] and "[reproduces nothing in particular]" in good[0]
    bad = [ln for ln in lines if ln.startswith("bad_range.toml")]
    assert len(bad) == 1 and "ERROR: components.pendulum.parameters.L" in bad[0]
    assert all("ERROR" in ln for ln in lines if ln.startswith("bad_"))


def test_list_all_good(tmp_path, capsys):
    (tmp_path / "a.toml").write_text(TINY.format(fmu="Pendulum"))
    rc, out, _ = run(capsys, ["list", tmp_path])
    assert rc == 0 and out.split() == ["a.toml", "tiny"]


def test_info_by_name(capsys):
    rc, out, err = run(capsys, ["info", "Pendulum"])
    assert rc == 0 and err == ""
    assert out.startswith("Pendulum (FMI 2.0 Co-Simulation)")
    for cap in ("canHandleVariableCommunicationStepSize", "canGetAndSetFMUstate", "canSerializeFMUstate",
                "canInterpolateInputs", "maxOutputDerivativeOrder"):
        assert cap in out
    rows = {ln.split()[0]: ln.split() for ln in out.splitlines() if ln.startswith("  ") and len(ln.split()) > 6}
    assert rows["L"][:8] == ["L", "parameter", "fixed", "Real", "m", "1", "1e-06", "1000000"]
    assert rows["phi"][:5] == ["phi", "output", "continuous", "Real", "rad"]
    assert "event indicators: none" in out


def test_info_event_indicators(tmp_path, capsys):
    # An FMU whose vendor annotation declares an indicator (Pendulum's XML plus the annotation).
    src = fmu_file("Pendulum")
    dst = tmp_path / "Annotated.fmu"
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                data = data.replace(b"<ModelVariables>", b'<VendorAnnotations><Tool name="clockwork"><EventIndicators>'
                                    b'<Indicator name="phi"/></EventIndicators></Tool></VendorAnnotations>'
                                    b"<ModelVariables>", 1)
            zout.writestr(item, data)
    rc, out, _ = run(capsys, ["info", dst])
    assert rc == 0 and "event indicators: phi" in out


def test_info_on_the_fmi3_build(capsys):
    from clockwork.paths import fmu_dir

    rc, out, err = run(capsys, ["info", fmu_dir(fmi_version=3) / "GrasshopperEscapement.fmu"])
    assert rc == 0 and err == ""
    assert out.startswith("GrasshopperEscapement (FMI 3.0 Co-Simulation)")
    flags = dict(ln.split()[:2] for ln in out.splitlines() if ln.startswith("  ") and len(ln.split()) == 2)
    assert flags["hasEventMode"] == "true" and flags["mightReturnEarlyFromDoStep"] == "false"
    # Its Float64 inputs (phi, w) take the master's polynomials by intermediate update.
    assert flags["providesIntermediateUpdate"] == "true" and "canInterpolateInputs" not in flags
    rows = {ln.split()[0]: ln.split() for ln in out.splitlines() if ln.startswith("  ") and len(ln.split()) > 6}
    assert rows["phi"][:5] == ["phi", "input", "continuous", "Float64", "rad"]
    assert rows["time"][1] == "independent"
    # The indicators of FMI 3.0's annotation, as in the FMI 2.0 build.
    assert "event indicators: event_indicator, event_indicator_turn" in out


# --- bad input: one line on stderr, exit code 2 --------------------------------

def _scene_with_fmu(tmp_path, fmu_bytes):
    (tmp_path / "X.fmu").write_bytes(fmu_bytes)
    f = tmp_path / "corrupt.toml"
    f.write_text(TINY.format(fmu="X.fmu"))
    return f


def _wrong_unit(tmp_path):
    f = tmp_path / "unit.toml"
    f.write_text(TINY.format(fmu="Pendulum").replace('fmu = "Pendulum"', 'fmu = "Pendulum"\nparameters = { L = "3 deg" }'))
    return f


def _file(tmp_path):
    f = tmp_path / "afile"
    f.write_text("x")
    return f


BAD_INPUT = [
    # argv (callables get tmp_path), substrings of the message
    (lambda t: ["validate", DATA / "bad_toml.toml"], ["bad_toml.toml", "line 5", "malformed TOML"]),
    (lambda t: ["validate", DATA / "bad_master_key.toml"], ["bad_master_key.toml", "master.stepp", "unknown key"]),
    (lambda t: ["validate", _wrong_unit(t)], ["unit.toml", "components.pendulum.parameters.L", "a unit of m"]),
    (lambda t: ["validate", DATA / "bad_fmu_path.toml"], ["bad_fmu_path.toml", "components.pendulum.fmu",
                                                           "no such FMU file"]),
    (lambda t: ["validate", _scene_with_fmu(t, b"\x00garbage\xff" * 10)], ["corrupt.toml", "components.pendulum.fmu",
                                                                            "X.fmu is not an FMU"]),
    (lambda t: ["validate", t / "missing.toml"], ["missing.toml", "no such scene file"]),
    (lambda t: ["run", GOOD, "--out", _file(t) / "below"], ["afile", "is a file, not a directory"]),
    (lambda t: ["run", GOOD, "--out", ""], ["output directory is empty"]),
    (lambda t: ["validate", GOOD, "--set", "pendulum.phi_start=400 deg"],
     ["good.toml", "--set pendulum.phi_start", "expected a value in [-3.14"]),
    (lambda t: ["validate", GOOD, "--set", "pendulum.phi_strt=1"], ["good.toml", "--set pendulum.phi_strt",
                                                                     "did you mean phi_start"]),
    (lambda t: ["validate", GOOD, "--set", "pendulum.Q"], ["good.toml", "--set pendulum.Q", "expected instance.parameter=value"]),
    (lambda t: ["run", GOOD, "--out", t, "--workers", "0"], ["--workers", "expected a positive integer"]),
    (lambda t: ["run", GOOD], ["run", "--out"]),
    (lambda t: [], ["required"]),
    (lambda t: ["frobnicate"], ["invalid choice"]),
    (lambda t: ["list", t / "nodir"], ["nodir", "no such directory"]),
    (lambda t: ["info", "NoSuchModel"], ["no FMU named NoSuchModel"]),
    (lambda t: ["info", DATA / "garbage.fmu"], ["garbage.fmu", "not a zip archive"]),
]


@pytest.mark.parametrize("make_argv, needles", BAD_INPUT, ids=[" ".join(str(x) for x in n) for _, n in BAD_INPUT])
def test_bad_input(tmp_path, capsys, make_argv, needles):
    rc, out, err = run(capsys, make_argv(tmp_path))
    assert_one_line_error(rc, err, *needles)


@pytest.mark.skipif(os.geteuid() == 0, reason="root can write into a read-only directory")
def test_unwritable_output_dir(tmp_path, capsys):
    d = tmp_path / "ro"
    d.mkdir()
    d.chmod(0o500)
    try:
        rc, out, err = run(capsys, ["run", GOOD, "--out", d])
    finally:
        d.chmod(0o700)
    assert_one_line_error(rc, err, "ro", "not writable")


# --- run: plumbing into the runner (a stand-in runner; the real one is the lead's) --------

@pytest.fixture
def fake_runner(monkeypatch):
    calls = []
    mod = types.ModuleType("clockwork.run.scene_run")

    def run_scene(scene, out_dir, workers=None, scheduler=None, progress=True, plot_process=None):
        calls.append((scene, out_dir, workers, scheduler, progress))
        if scene.components["pendulum"].parameters.get("Q") == 13.0:
            raise SimulationError("fmi2DoStep failed", time=0.25, instance="pendulum")
        return {"points_total": 1, "files": ["summary.json"], "headlines": []}

    mod.run_scene = run_scene
    monkeypatch.setitem(sys.modules, "clockwork.run.scene_run", mod)
    return calls


def test_run_passes_scene_and_options(tmp_path, capsys, fake_runner):
    out_dir = tmp_path / "out"
    rc, out, err = run(capsys, ["run", GOOD, "--out", out_dir, "--workers", "3", "--scheduler", "tcp://x:8786",
                                "--no-progress", "--set", "pendulum.Q=700"])
    assert rc == 0, err
    (scene, got_dir, workers, scheduler, progress), = fake_runner
    assert out_dir.is_dir() and Path(got_dir) == out_dir
    assert (workers, scheduler, progress) == (3, "tcp://x:8786", False)
    assert scene.components["pendulum"].parameters["Q"] == 700.0
    assert scene.overrides == ("pendulum.Q=700",)


def test_run_simulation_error_exits_1(tmp_path, capsys, fake_runner):
    rc, out, err = run(capsys, ["run", GOOD, "--out", tmp_path / "o", "--set", "pendulum.Q=13"])
    assert_one_line_error(rc, err, "t = 0.25 s, pendulum: fmi2DoStep failed", code=1)


def test_run_real_runner(tmp_path, capsys):
    runner = pytest.importorskip("clockwork.run.scene_run")
    if not hasattr(runner, "run_scene"):
        pytest.skip("clockwork.run.scene_run.run_scene not written yet")
    f = tmp_path / "tiny.toml"
    f.write_text(TINY.format(fmu="Pendulum"))
    out_dir = tmp_path / "out"
    rc, out, err = run(capsys, ["run", f, "--out", out_dir, "--no-progress"])
    assert rc == 0, err
    assert any(out_dir.iterdir())


def test_python_m_clockwork(tmp_path):
    import subprocess

    p = subprocess.run([sys.executable, "-m", "clockwork", "validate", str(DATA / "bad_range.toml")],
                       capture_output=True, text=True, env={**os.environ, "CLOCKWORK_FMU_DIR": str(FMU_DIR)})
    assert p.returncode == 2
    assert p.stderr.count("\n") == 1 and "components.pendulum.parameters.L" in p.stderr


def test_unwritable_output_dir_simulated(tmp_path, capsys, monkeypatch):
    from clockwork.results import files as results

    def denied(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(results.tempfile, "mkstemp", denied)
    rc, out, err = run(capsys, ["run", GOOD, "--out", tmp_path])
    assert_one_line_error(rc, err, str(tmp_path), "not writable")


# --- progress bars: on a terminal only --------------------------------------------------

LONG_RUN_S = 30000.0


def _long_run(tmp_path, stderr):
    """A run of a few seconds (the bars appear after 1 s), its stderr on
    `stderr`: 30,000 s of the clock, 3 to 4 s of stepping on this machine
    (6000 s had become shorter than the bar's 1 s delay as the master sped up)."""
    import subprocess

    from cwtest import CLOCK_SCENE, ROOT

    scene = tmp_path / "long.toml"
    scene.write_text(CLOCK_SCENE.format(stop=LONG_RUN_S, sweep="").replace('ticks = "pendulum"\n', 'interval = "10 s"\n'))
    env = dict(os.environ, CLOCKWORK_FMU_DIR=str(FMU_DIR), CLOCKWORK_CACHE="off", PYTHONPATH=str(ROOT))
    return subprocess.run([sys.executable, "-m", "clockwork", "run", str(scene), "--out", str(tmp_path / "o")],
                          env=env, stdout=subprocess.PIPE, stderr=stderr, timeout=300)


def test_no_progress_bar_into_a_pipe_or_a_file(tmp_path):
    """stderr in a pipe (a CI log): nothing at all on it for a good run."""
    import subprocess

    r = _long_run(tmp_path, subprocess.PIPE)
    assert r.returncode == 0, r.stderr
    assert r.stderr == b"", r.stderr[:300]


def test_a_progress_bar_on_a_terminal(tmp_path):
    import fcntl
    import pty
    import struct
    import termios
    import threading

    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # 0 columns: an empty bar
    seen = bytearray()

    def drain():  # read while it runs: a full terminal buffer would stop the run
        while True:
            try:
                chunk = os.read(master, 65536)
            except OSError:  # EIO: the other end is closed
                return
            if not chunk:
                return
            seen.extend(chunk)

    reader = threading.Thread(target=drain, daemon=True)
    reader.start()
    try:
        r = _long_run(tmp_path, slave)
    finally:
        os.close(slave)
        reader.join(10)
        os.close(master)
    assert r.returncode == 0
    # the bar reached its end (tqdm writes the total as "3e+04"), redrawn in place
    assert re.search(rb"\| (\S+)/\1 s \[", seen) and b"\r" in seen, bytes(seen[:300])


@pytest.mark.parametrize("given, expected", [(None, "1"), ("3", "3")])
def test_the_command_keeps_openblas_to_one_thread_unless_told(given, expected):
    """The `clockwork` command (console()) sets OPENBLAS_NUM_THREADS=1 before
    numpy loads, for itself and the processes it starts (their spinning
    threads took the cores of the plot process and the workers); a value
    the user gave stands."""
    import subprocess

    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    if given is not None:
        env["OPENBLAS_NUM_THREADS"] = given
    code = ("import os, sys; sys.argv = ['clockwork', '--version']; from clockwork.cli import console\n"
            "try:\n    console()\nexcept SystemExit:\n    pass\n"
            "print(os.environ.get('OPENBLAS_NUM_THREADS'), 'numpy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.split()[-2:] == [expected, "False"]


def test_a_toml_scene_loads_without_the_readers_of_other_formats():
    """A TOML scene's run (Fig. 4(a), Hoyng's clock) starts without the SSP,
    OSP and lone-FMU readers: load_scene imports each for its own files."""
    import subprocess

    code = ("import sys; from clockwork.run.catalog import load_scene\n"
            "load_scene('ziemkiewicz_fig4a')\n"
            "print(sorted(m for m in sys.modules if m.startswith(('clockwork.scene.ssp', 'clockwork.scene.osp', "
            "'clockwork.scene.fmu_alone'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split("\n")[-2] == "[]"
