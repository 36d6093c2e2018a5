"""Paths that name something other than a regular file where a file is read
(a FIFO without a writer, a socket, a character device, a directory, a
huge sparse file): refused with one line before they are opened in a way
that blocks or reads without end (clockwork/files.py, the one place files
a user names are opened for reading)."""

from __future__ import annotations

import os
import signal
import socket
from contextlib import contextmanager

import pytest

from cwtest import CLOCK_SCENE, assert_one_line_error, fmu_file, run_cli


@contextmanager
def _deadline(seconds: int = 20):
    """A hang (an open() of a FIFO blocks until a writer appears) fails the test instead."""
    def expired(*_):
        raise TimeoutError("hung")

    old = signal.signal(signal.SIGALRM, expired)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def _make(kind: str, path) -> str:
    """Put a `kind` at `path` (or name one): its path."""
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "socket":
        s = socket.socket(socket.AF_UNIX)
        s.bind(str(path))
        _SOCKETS.append(s)
    elif kind == "directory":
        os.mkdir(path)
    elif kind == "sparse":  # 64 GiB that take no disk: refused by its size, not read
        with open(path, "wb") as f:
            f.truncate(64 << 30)
    elif kind == "/dev/zero":  # by a link of the name the place expects (X.fmu, X.ssp)
        os.symlink("/dev/zero", path)
    return str(path)


_SOCKETS: list = []
KINDS = ["fifo", "socket", "/dev/zero", "directory"]
WHAT = {"fifo": "a FIFO", "socket": "a socket", "/dev/zero": "a character device", "directory": "a directory",
        "sparse": "bytes"}


@pytest.fixture(autouse=True)
def _close_sockets():
    yield
    while _SOCKETS:
        _SOCKETS.pop().close()


def _scene(tmp_path, text_edit=lambda s: s) -> str:
    fmu_file("Pendulum")
    path = tmp_path / "clock.toml"
    path.write_text(text_edit(CLOCK_SCENE.format(stop=0.5, sweep="")))
    return str(path)


# Where a user names a file clockwork reads: the command line, given the path of the special file.
PLACES = {
    "--input": lambda tmp, p: ["validate", fmu_file("Pendulum"), "--input", p],
    "scene": lambda tmp, p: ["validate", p],
    "scene.toml": lambda tmp, p: ["validate", p],
    "X.fmu": lambda tmp, p: ["validate", p],
    "info X.fmu": lambda tmp, p: ["info", p],
    "X.ssp": lambda tmp, p: ["validate", p],
    "X.ssd": lambda tmp, p: ["validate", p],
    "compare RESULT.csv": lambda tmp, p: ["compare", p, "GrasshopperClock"],
    "run --input": lambda tmp, p: ["run", fmu_file("Pendulum"), "--input", p, "--out", tmp / "out", "--no-progress"],
    "fit --data": lambda tmp, p: ["fit", "ziemkiewicz_fig4a", "--data", p, "--free", "pendulum.Q", "--out", tmp / "out"],
}
SUFFIX = {"scene.toml": ".toml", "X.fmu": ".fmu", "info X.fmu": ".fmu", "X.ssp": ".ssp", "X.ssd": ".ssd",
          "compare RESULT.csv": ".csv", "fit --data": ".csv"}


@pytest.mark.parametrize("kind", KINDS + ["sparse"])
@pytest.mark.parametrize("place", list(PLACES))
def test_a_path_that_is_no_regular_file_is_refused_with_one_line(capsys, tmp_path, place, kind):
    if kind == "directory" and place in ("compare RESULT.csv",):
        pytest.skip("a directory is a libcosim result there")
    if kind == "sparse" and place in ("X.fmu", "info X.fmu", "X.ssp", "X.ssd"):
        pytest.skip("a zip archive's size is bounded by its directory (tests/test_fmu_hardening.py)")
    path = _make(kind, tmp_path / f"thing{SUFFIX.get(place, '')}")
    with _deadline():
        rc, _, err = run_cli(capsys, PLACES[place](tmp_path, path))
    if kind == "sparse" and place == "compare RESULT.csv":  # read as a stream: its first line is too long
        assert_one_line_error(rc, err, path, "line 1")
    else:  # an FMU is named by its real path: /dev/zero
        assert_one_line_error(rc, err, WHAT[kind])
        assert path in err or "/dev/zero" in err, err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("key", ["fmu", "inputs"])
def test_a_scene_that_names_a_special_file_is_refused(capsys, tmp_path, key, kind):
    """The same for the files a scene names: a component's FMU, its input file."""
    special = _make(kind, tmp_path / ("p.fmu" if key == "fmu" else "in.csv"))
    if key == "fmu":
        scene = _scene(tmp_path, lambda s: s.replace('fmu = "Pendulum"', f'fmu = "{special}"', 1))
    else:
        scene = _scene(tmp_path, lambda s: s + f'\n[inputs]\nfile = "{special}"\n')
    with _deadline():
        rc, _, err = run_cli(capsys, ["validate", scene])
    assert_one_line_error(rc, err, WHAT[kind])
    assert special in err or "/dev/zero" in err, err


@pytest.mark.parametrize("kind", ["fifo", "socket", "/dev/zero"])
def test_an_output_file_that_is_a_special_file_is_refused(capsys, tmp_path, kind):
    target = _make(kind, tmp_path / "grade.json")
    csv = tmp_path / "r.csv"
    csv.write_text("time,x\n0,1\n")
    with _deadline():
        rc, _, err = run_cli(capsys, ["compare", csv, "GrasshopperClock", "--json", target])
    assert_one_line_error(rc, err, target)


def test_open_regular_does_not_block_on_a_fifo_and_reads_a_file(tmp_path):
    from clockwork.files import NotRegularFile, open_regular, read_regular

    os.mkfifo(tmp_path / "f")
    with _deadline(5), pytest.raises(NotRegularFile, match="FIFO"):
        open_regular(tmp_path / "f")
    (tmp_path / "a").write_bytes(b"abc")
    assert read_regular(tmp_path / "a") == b"abc"
    with pytest.raises(NotRegularFile, match="at most 2 bytes"):
        read_regular(tmp_path / "a", limit=2)
    with pytest.raises(FileNotFoundError):
        open_regular(tmp_path / "none")


@pytest.mark.parametrize("kind", ["fifo", "socket", "/dev/zero", "directory"])
def test_plot_out_onto_a_special_file_is_refused(capsys, tmp_path, kind):
    from cwtest import test_fmu

    rc, _, err = run_cli(capsys, ["run", test_fmu("TestDecay"), "--out", tmp_path / "r", "--no-progress", "--no-plot"])
    assert rc == 0, err
    target = _make(kind, tmp_path / "page.png")
    with _deadline():
        rc, _, err = run_cli(capsys, ["plot", tmp_path / "r", "--out", target])
    assert_one_line_error(rc, err, target, "--out")
    assert not (tmp_path / "page.png").is_file()


@pytest.mark.parametrize("kind", ["fifo", "/dev/zero", "directory"])
@pytest.mark.parametrize("entry", ["resources/escapement.ssv", "resources/Pendulum.fmu"])
def test_an_ssd_that_names_a_special_file_is_refused(capsys, tmp_path, entry, kind):
    """The files an .ssd names beside it: a parameter file (.ssv), an FMU."""
    from test_ssp import fixture_dir

    d = fixture_dir(tmp_path, "flat10")
    (d / entry).unlink()
    _make(kind, d / entry)
    with _deadline():
        rc, _, err = run_cli(capsys, ["validate", d / "SystemStructure.ssd"])
    lines = [ln for ln in err.splitlines() if not ln.startswith(("clockwork: warning:", "clockwork: note:"))]
    assert_one_line_error(rc, "\n".join(lines), WHAT[kind])
    assert entry.split("/")[-1] in err or "/dev/zero" in err, err
