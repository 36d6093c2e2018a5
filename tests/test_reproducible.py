"""The FMU archives are the same bytes wherever they are built.

tools/fmuzip.py packs a staged FMU with sorted entries, fixed dates and
modes; the compiler gets -ffile-prefix-map so that no build folder is
written into a binary. A fresh CMake build in another folder (as a wheel
build does, in a temporary folder) must give the checkout's archive.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from cwtest import BUILD_DIR, FMU_DIR, ROOT, fmu_file

sys.path.insert(0, str(ROOT / "tools"))
import fmuzip  # noqa: E402


def _stage(root: Path, order: list[str], mode: int, mtime: int) -> Path:
    files = {"modelDescription.xml": b"<x/>", "binaries/linux64/M.so": b"\x7fELF...", "sources/a.c": b"int a;",
             "sources/b.c": b"int b;", "documentation/index.html": b"<html/>"}
    for name in order:
        p = root / name
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(files[name])
        os.chmod(p, mode)
        os.utime(p, (mtime, mtime))
    return root


def test_the_same_files_pack_to_the_same_bytes(tmp_path, monkeypatch):
    monkeypatch.delenv("SOURCE_DATE_EPOCH", raising=False)
    names = ["modelDescription.xml", "binaries/linux64/M.so", "sources/a.c", "sources/b.c", "documentation/index.html"]
    a = _stage(tmp_path / "a", names, 0o644, 1_700_000_000)
    b = _stage(tmp_path / "b", list(reversed(names)), 0o600, 1_800_000_000)  # other order, umask, time
    fmuzip.pack(a, tmp_path / "a.fmu")
    fmuzip.pack(b, tmp_path / "b.fmu")
    assert (tmp_path / "a.fmu").read_bytes() == (tmp_path / "b.fmu").read_bytes()
    with zipfile.ZipFile(tmp_path / "a.fmu") as z:
        assert [i.filename for i in z.infolist()] == sorted(names)
        assert {i.date_time for i in z.infolist()} == {(1980, 1, 1, 0, 0, 0)}
        assert (z.getinfo("binaries/linux64/M.so").external_attr >> 16) & 0o777 == 0o755
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    fmuzip.pack(a, tmp_path / "c.fmu")
    with zipfile.ZipFile(tmp_path / "c.fmu") as z:
        assert z.infolist()[0].date_time[:3] == (2023, 11, 14)


@pytest.mark.skipif(shutil.which("cmake") is None or not (BUILD_DIR / "CMakeCache.txt").exists(),
                    reason="needs cmake and the checkout's build")
def test_a_build_in_another_folder_gives_the_checkouts_fmu(tmp_path):
    ours = fmu_file("Pendulum")
    if FMU_DIR.resolve() != (ROOT / "fmus").resolve():
        pytest.skip("the FMUs under test are not the checkout's build")
    build = tmp_path / "elsewhere"
    env = dict(os.environ)
    env.pop("SOURCE_DATE_EPOCH", None)
    for cmd in (["cmake", "-S", ROOT, "-B", build, "-G", "Ninja", f"-DCW_FMU_DIR={build / 'fmus'}",
                 f"-DCW_LIB_DIR={build / 'lib'}", f"-DPython3_EXECUTABLE={sys.executable}"],
                ["cmake", "--build", build, "--target", "Pendulum_fmu"]):
        r = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, env=env)
        assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    digest = [hashlib.sha256(p.read_bytes()).hexdigest() for p in (ours, build / "fmus" / "Pendulum.fmu")]
    assert digest[0] == digest[1], "rebuild the checkout's FMUs (cmake --build build) and compare again"
