"""Hostile FMUs: what `run` refuses before stepping, `info` and `validate`
refuse too (with the file and key), and nothing is unzipped past a bound.

Each class is tried on several FMUs made from Pendulum.fmu: model
identifiers that are not plain names, binaries that are not a shared
library for this machine, archives over the size bounds, algebraic loops
between feedthrough FMUs, and entry names with "../".
"""

from __future__ import annotations

import platform
import struct
import sys
import zipfile
from pathlib import Path

import pytest

from cwtest import FMU_DIR, assert_one_line_error, fmu_file, run_cli
from clockwork.fmi import archive as fmu, description

BINARY = "binaries/linux64/Pendulum.so"


@pytest.fixture(autouse=True)
def _env(monkeypatch, tmp_path):
    fmu_file("Pendulum")
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))
    monkeypatch.setenv("CLOCKWORK_CACHE", str(tmp_path / "cache"))
    monkeypatch.delenv("CLOCKWORK_MAX_FMU_MB", raising=False)
    description._MD_CACHE.clear()
    fmu._extracted.clear()


def _copy(tmp_path: Path, name: str, change=None, extra: dict | None = None) -> Path:
    """Pendulum.fmu with change(entry name, bytes) -> bytes applied, plus `extra` entries."""
    out = tmp_path / f"{name}.fmu"
    with zipfile.ZipFile(FMU_DIR / "Pendulum.fmu") as src, zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as dst:
        for info in src.infolist():
            data = src.read(info.filename)
            dst.writestr(info.filename, change(info.filename, data) if change else data)
        for n, data in (extra or {}).items():
            dst.writestr(n, data)
    return out


def _scene(tmp_path: Path, fmu_path: Path) -> Path:
    f = tmp_path / "one.toml"
    f.write_text(f'[scene]\ntitle = "one"\n[components.pendulum]\nfmu = "{fmu_path}"\n'
                 '[experiment]\nstop = "0.2 s"\n[master]\nstep = "0.1 s"\n')
    return f


def _refused_everywhere(capsys, tmp_path, path: Path, *needles):
    """info, validate and run each refuse with one line (exit 2); nothing is run or cached."""
    scene = _scene(tmp_path, path)
    for argv in (["info", path], ["validate", scene], ["run", scene, "--out", tmp_path / "out", "--no-progress"]):
        rc, _, err = run_cli(capsys, argv)
        assert_one_line_error(rc, err, str(path), *needles, code=2)
    assert not (tmp_path / "out" / "summary.json").exists()
    cached = tmp_path / "cache" / "fmus"
    assert not cached.exists() or not any(cached.iterdir()), list(cached.iterdir())


# --- modelIdentifier -------------------------------------------------------------

IDENTIFIERS = ["../../x/Pendulum", "/tmp/Pendulum", "sub/Pendulum", "..", ".", "", "Pendulum\\..\\x",
               "Pend&#10;ulum", "Pend&#9;ulum", "P" * 300]


@pytest.mark.parametrize("ident", IDENTIFIERS)
def test_a_model_identifier_that_is_not_a_plain_name_is_refused(capsys, tmp_path, ident):
    def change(name, data):
        if name == "modelDescription.xml":
            return data.replace(b'modelIdentifier="Pendulum"', f'modelIdentifier="{ident}"'.encode())
        return data
    path = _copy(tmp_path, "ident", change)
    _refused_everywhere(capsys, tmp_path, path, "modelIdentifier")


def _renamed(tmp_path: Path, ident: str, binary: str | None = None) -> Path:
    """Pendulum.fmu whose modelIdentifier is `ident` and whose binary is named `binary`."""
    def change(name, data):
        if name == "modelDescription.xml":
            return data.replace(b'modelIdentifier="Pendulum"', f'modelIdentifier="{ident}"'.encode())
        return data
    out = tmp_path / "renamed.fmu"
    with zipfile.ZipFile(FMU_DIR / "Pendulum.fmu") as src, zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as dst:
        for info in src.infolist():
            name = BINARY.replace("Pendulum.so", binary) if info.filename == BINARY and binary else info.filename
            dst.writestr(name, change(info.filename, src.read(info.filename)))
    return out


# File names fmpy loads (binaries/<platform>/<modelIdentifier>.so) that are no C names:
# exporters write them (a hyphen), and fmpy, libcosim and ecos run them.
FILE_NAMES = ["Pendulum-1", "pendulum-model.v2", "Pend ulum", "Pendulum.so", "P\u00e9ndule", "-Pendulum"]


@pytest.mark.parametrize("ident", FILE_NAMES)
@pytest.mark.parametrize("engine", ["python", "compiled"])
def test_a_model_identifier_that_is_a_file_name_runs(capsys, tmp_path, ident, engine):
    path = _renamed(tmp_path, ident, f"{ident}.so")
    rc, out, err = run_cli(capsys, ["validate", path])
    assert rc == 0, err
    rc, _, err = run_cli(capsys, ["run", path, "--out", tmp_path / "out", "--no-progress",
                                  "--set", "experiment.stop=0.2", "--set", f"master.engine={engine}"])
    assert rc == 0, err
    rc, _, err = run_cli(capsys, ["run", FMU_DIR / "Pendulum.fmu", "--out", tmp_path / "ref", "--no-progress",
                                  "--set", "experiment.stop=0.2", "--set", f"master.engine={engine}"])
    assert rc == 0, err
    assert (tmp_path / "out" / "timeseries.csv").read_bytes() == (tmp_path / "ref" / "timeseries.csv").read_bytes()


@pytest.mark.parametrize("ident", ["Pendulum-1", "Pendulum.so"])
def test_a_binary_that_the_model_identifier_does_not_name_is_said(capsys, tmp_path, ident):
    """The platform folder holds Pendulum.so, the modelIdentifier names another file: the line says both."""
    path = _renamed(tmp_path, ident)
    scene = _scene(tmp_path, path)
    for argv in (["validate", scene], ["run", scene, "--out", tmp_path / "out", "--no-progress"], ["validate", path]):
        rc, _, err = run_cli(capsys, argv)
        assert_one_line_error(rc, err, str(path), f"binaries/linux64/{ident}.so", "binaries/linux64/ holds Pendulum.so",
                              f"modelIdentifier {ident!r}", code=2)
    assert not (tmp_path / "out" / "summary.json").exists()


def test_a_binary_in_another_platform_folder_is_said(capsys, tmp_path):
    path = tmp_path / "moved.fmu"
    with zipfile.ZipFile(FMU_DIR / "Pendulum.fmu") as src, zipfile.ZipFile(path, "w") as dst:
        for info in src.infolist():
            name = info.filename.replace("binaries/linux64/", "binaries/x86_64-linux/")
            dst.writestr(name, src.read(info.filename))
    rc, _, err = run_cli(capsys, ["validate", path])
    assert_one_line_error(rc, err, str(path), "Pendulum.so is in binaries/x86_64-linux/, not in binaries/linux64/",
                          code=2)


# --- binaries that are not a shared library for this machine ---------------------------

def _patched(offset: int, value: bytes):
    def patch(data: bytes) -> bytes:
        return data[:offset] + value + data[offset + len(value):]
    return patch


BINARIES = {
    "text": lambda data: b"#!/bin/sh\necho not a library\n",
    "empty": lambda data: b"",
    "truncated ELF header": lambda data: data[:10],
    "32-bit ELF": _patched(4, b"\x01"),
    "relocatable object (ET_REL)": _patched(16, struct.pack("<H", 1)),
    "executable (ET_EXEC)": _patched(16, struct.pack("<H", 2)),
    "another processor": _patched(18, struct.pack("<H", 183 if platform.machine() != "aarch64" else 62)),
    "a Windows DLL": lambda data: b"MZ" + data[2:],
}


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="ELF checks are for Linux")
@pytest.mark.parametrize("kind", list(BINARIES))
def test_a_binary_that_is_not_a_shared_library_is_refused_by_validate(capsys, tmp_path, kind):
    path = _copy(tmp_path, "bin", lambda n, d: BINARIES[kind](d) if n == BINARY else d)
    scene = _scene(tmp_path, path)
    for argv in (["validate", scene], ["run", scene, "--out", tmp_path / "out", "--no-progress"]):
        rc, _, err = run_cli(capsys, argv)
        assert_one_line_error(rc, err, str(path), BINARY, code=2)
    assert "cmake" not in err  # not one of the project's FMUs: no rebuild advice


def test_rebuild_advice_only_for_the_projects_own_fmus(capsys, tmp_path):
    gone = _copy(tmp_path, "Pendulum", lambda n, d: d)  # named like ours, but not in fmus/
    with zipfile.ZipFile(gone) as z, zipfile.ZipFile(tmp_path / "nobin.fmu", "w") as out:
        for i in z.infolist():
            if i.filename != BINARY:
                out.writestr(i, z.read(i.filename))
    rc, _, err = run_cli(capsys, ["validate", _scene(tmp_path, tmp_path / "nobin.fmu")])
    assert_one_line_error(rc, err, "no binary for this platform", code=2)
    assert "cmake" not in err and "linux64" in err
    assert "cmake --build build" in description._rebuild_advice(FMU_DIR / "Pendulum.fmu") or \
        not description.in_checkout()


# --- size bounds ---------------------------------------------------------------------

def test_an_fmu_that_unzips_past_the_bound_is_refused_and_nothing_is_cached(capsys, tmp_path, monkeypatch):
    monkeypatch.setenv("CLOCKWORK_MAX_FMU_MB", "2")
    path = _copy(tmp_path, "bomb", extra={"resources/zeros.bin": bytes(3 * 2**20)})
    assert path.stat().st_size < 200_000  # compresses well: the bound is on what it unzips to
    _refused_everywhere(capsys, tmp_path, path, "unzips to", "CLOCKWORK_MAX_FMU_MB")


def test_many_small_entries_past_the_bound_are_refused(capsys, tmp_path, monkeypatch):
    monkeypatch.setattr(description, "MAX_ENTRIES", 50)
    path = _copy(tmp_path, "many", extra={f"resources/f{k}.txt": b"x" for k in range(60)})
    _refused_everywhere(capsys, tmp_path, path, "entries")


def test_a_huge_model_description_is_refused_before_it_is_read(capsys, tmp_path):
    pad = b"<!--" + b" " * (description.MAX_DESCRIPTION_BYTES + 1) + b"-->\n"
    path = _copy(tmp_path, "hugexml", lambda n, d: d.replace(b"?>", b"?>" + pad, 1)
                 if n == "modelDescription.xml" else d)
    _refused_everywhere(capsys, tmp_path, path, "modelDescription.xml", "not read")


# --- algebraic loops between feedthrough FMUs -------------------------------------------
# Each has no solution: an escapement's event indicator is its input angle
# shifted by a constant, so going round the loop shifts it again.

LOOPS = {
    "two escapements": ({"e1": "GrasshopperEscapement", "e2": "GrasshopperEscapement"},
                        ["e1.event_indicator -> e2.phi", "e2.event_indicator -> e1.phi"], "e1 -> e2 -> e1"),
    "one feeding itself": ({"e1": "GrasshopperEscapement"}, ["e1.event_indicator -> e1.phi"], "e1 -> e1"),
    "three instances": ({"e1": "GrasshopperEscapement", "c": "ChronometerEscapement", "d": "Drag"},
                        ["e1.event_indicator -> c.phi", "c.event_indicator_turn -> d.w",
                         "c.event_indicator_lower -> e1.phi"], "e1 -> c -> e1"),
}


@pytest.mark.parametrize("case", list(LOOPS))
def test_an_algebraic_loop_is_named_and_one_without_a_solution_fails_in_one_line(capsys, tmp_path, case):
    comps, links, name = LOOPS[case]
    f = tmp_path / "loop.toml"
    f.write_text('connections = [' + ", ".join(f'"{c}"' for c in links) + ']\n[scene]\ntitle = "loop"\n'
                 + "".join(f'[components.{n}]\nfmu = "{m}"\n' for n, m in comps.items())
                 + '[experiment]\nstop = "1 s"\n')
    rc, out, err = run_cli(capsys, ["validate", f])
    assert rc == 0 and f"note: algebraic loop {name} (through " in out and '"solve")' in out, out + err
    rc, _, err = run_cli(capsys, ["run", f, "--out", tmp_path / "out", "--no-progress"])
    assert_one_line_error(rc, err, "t = 0.0 s: ", f"algebraic loop {name} did not converge", code=1)
    # Broken by a one-step delay it runs (the escapements' outputs stay bounded).
    rc, _, err = run_cli(capsys, ["run", f, "--out", tmp_path / "out", "--no-progress",
                                  "--set", "master.algebraic_loops=delay"])
    assert rc == 0, err


# --- entry names with ../ -------------------------------------------------------------

def test_an_fmu_with_dotdot_entries_does_not_damage_the_cache(capsys, tmp_path):
    path = _copy(tmp_path, "dotdot", extra={"../escaped.txt": b"x", "resources/../../up.txt": b"y",
                                            "/abs.txt": b"z"})
    scene = _scene(tmp_path, path)
    for k in range(3):
        fmu._extracted.clear()  # as a new process: the cache entry is checked again
        rc, _, err = run_cli(capsys, ["run", scene, "--out", tmp_path / "out", "--no-progress"])
        assert rc == 0 and "damaged" not in err and "warning" not in err, (k, err)
    assert not (tmp_path / "cache" / "escaped.txt").exists() and not (tmp_path / "escaped.txt").exists()


# --- what only loading tells: validate loads and instantiates each FMU as run does --------

LOAD_FAILURES = {
    "a position-independent executable": (lambda n, d: Path("/bin/true").read_bytes() if n == BINARY else d,
                                          "cannot load"),
    "another model's GUID": (lambda n, d: d.replace(b'guid="{', b'guid="{0', 1) if n == "modelDescription.xml"
                             else d, "GUID"),
}


@pytest.mark.skipif(not Path("/bin/true").exists(), reason="needs /bin/true")
@pytest.mark.parametrize("case", list(LOAD_FAILURES))
def test_validate_refuses_what_only_loading_shows(capsys, tmp_path, case):
    change, needle = LOAD_FAILURES[case]
    path = _copy(tmp_path, "load", change)
    scene = _scene(tmp_path, path)
    for argv in (["validate", scene], ["run", scene, "--out", tmp_path / "out", "--no-progress"]):
        rc, _, err = run_cli(capsys, argv)
        assert_one_line_error(rc, err, needle, code=2)
    rc, _, err = run_cli(capsys, ["validate", scene])
    assert "components.pendulum.fmu" in err
