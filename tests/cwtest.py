"""Paths shared by the test suites (import as `from cwtest import ...`).

A module with its own name: several test folders have a conftest.py, and
`from conftest import` would pick whichever pytest loaded last.
"""

import os
import signal
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FMU_DIR = Path(os.environ.get("CW_FMU_DIR", ROOT / "fmus"))
BUILD_DIR = Path(os.environ.get("CW_BUILD_DIR", ROOT / "build"))


# FMUs built for the tests only (tests/models, by CMake into build/test-fmus).
TEST_FMU_DIR = Path(os.environ.get("CW_TEST_FMU_DIR", BUILD_DIR / "test-fmus"))


def test_fmu(name: str) -> Path:
    path = TEST_FMU_DIR / f"{name}.fmu"
    if not path.exists():
        pytest.fail(f"{path} is missing: build the test FMUs first (cmake --build build)")
    return path


test_fmu.__test__ = False  # a helper, not a test


def fmu_file(name: str) -> Path:
    path = FMU_DIR / f"{name}.fmu"
    if not path.exists():
        pytest.fail(f"{path} is missing: build the FMUs first (cmake --build build)")
    return path


# A grasshopper clock a fraction of a second long: `{stop}` in seconds, and
# `{sweep}` (a [sweep] table, plots...) appended to the scene.
CLOCK_SCENE = textwrap.dedent("""\
    connections = [
      "pendulum.phi -> escapement.phi",
      "pendulum.w -> escapement.w",
      "escapement.tau -> pendulum.tau_escapement",
    ]

    [scene]
    title = "clock"

    [components.pendulum]
    fmu = "Pendulum"
    parameters = {{ Q = 1000, phi_start = "6 deg" }}

    [components.escapement]
    fmu = "GrasshopperEscapement"
    parameters = {{ torque = "0.4 N.cm", phi_r = "2 deg" }}

    [experiment]
    stop = "{stop} s"

    [master]
    step = "0.01 s"
    event_location = true

    [record]
    outputs = ["pendulum.phi"]
    ticks = "pendulum"

    [analysis]
    kind = "time_series"
    {sweep}
    """)


def run_cli(capsys, argv):
    """clockwork's CLI in this process: (exit code, stdout, stderr)."""
    from clockwork import cli

    rc = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return rc, out, err


def assert_one_line_error(rc, err, *needles, code=2):
    """Exit `code` and exactly one stderr line "clockwork: error: ..." holding every needle."""
    assert rc == code, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("clockwork: error: "), err
    assert "Traceback" not in err
    for n in needles:
        assert n in lines[0], (n, lines[0])


def default_stop_signals() -> None:
    """preexec_fn of a child that a test sends SIGINT, SIGTERM or SIGHUP:
    the three at their defaults, as in a terminal. The test run itself may
    ignore them (nohup ignores SIGHUP; a background job of a shell without
    job control ignores SIGINT), a child inherits an ignored signal, and
    clockwork rightly keeps an ignored signal ignored."""
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, signal.SIG_DFL)
