"""The bundled FMUs carry Windows binaries, and the FMI 3.0 ones Linux on
64-bit Arm binaries (cmake/platforms.cmake), and they compute the Linux
x86-64 binaries' numbers.

The DLLs are cross-compiled with mingw-w64 from the same sources and run
under wine by the harness (tools/platcheck/harness.c) built for Windows;
the same harness built for Linux runs the .so files. Where a DLL's numbers
are not the .so's bit for bit, the difference is the C library's: the DLLs
carry mingw-w64's sin, cos, exp, log and pow, the .so files call glibc's,
and the two round differently in the last bit for some arguments (the
probe below counts them). A last-bit difference in one step's right-hand
side is carried on by the integrator as any rounding is, so it stays far
below the integrator's own error: the test bounds it by the model's rtol
(the accuracy the model promises), and requires bit-identity of models
without an integrator tolerance.

The aarch64-linux .so files (FMI 3.0 only: FMI 2.0 names no such platform)
are cross-compiled with Debian's gcc-aarch64-linux-gnu and run with the
harness under qemu-user against Debian's arm64 glibc.

Skipped outside CI where mingw-w64, wine, the Arm cross compiler or
qemu-user is missing (tools/setup.sh installs them as root); in CI a
missing one fails.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile

import numpy as np
import pytest

from cwtest import BUILD_DIR, FMU_DIR, ROOT

sys.path.insert(0, str(ROOT / "tools" / "platcheck"))
import platcheck  # noqa: E402

MODELS = sorted(p.name for p in (ROOT / "src_c" / "models").iterdir() if (p / "model.toml").exists())
# What a DLL may import: Windows' own DLLs only (no libgcc, no winpthread).
WINDOWS_DLLS = {"KERNEL32.dll", "msvcrt.dll"}


def _needs(what: str, ok: bool) -> None:
    if not ok:
        if os.environ.get("CI"):
            pytest.fail(f"{what} is missing in CI: tools/setup.sh installs it")
        pytest.skip(f"{what} is missing (tools/setup.sh installs it as root)")


@pytest.fixture(scope="module")
def windows_build():
    _needs("the Windows build (mingw-w64)", (BUILD_DIR / "x86_64-windows" / "platcheck.exe").exists())
    return BUILD_DIR / "x86_64-windows"


def _pe_table(dll, heading: str) -> list[str]:
    """Imported DLL names, or exported names, from mingw-w64's objdump."""
    out = subprocess.run(["x86_64-w64-mingw32-objdump", "-p", str(dll)], capture_output=True, text=True,
                         check=True).stdout
    if heading == "imports":
        return [ln.split("DLL Name:")[1].strip() for ln in out.splitlines() if "DLL Name:" in ln]
    table = out.split("[Ordinal/Name Pointer] Table", 1)[1].split("\n\n", 1)[0]
    return [ln.split()[-1] for ln in table.splitlines() if ln.strip()]


def _so_exports(so) -> list[str]:
    out = subprocess.run(["nm", "-D", "--defined-only", str(so)], capture_output=True, text=True, check=True).stdout
    return [ln.split()[-1] for ln in out.splitlines() if ln.strip()]


@pytest.fixture(scope="module")
def aarch64_build():
    _needs("the aarch64-linux build (gcc-aarch64-linux-gnu)", (BUILD_DIR / "aarch64-linux" / "platcheck").exists())
    return BUILD_DIR / "aarch64-linux"


@pytest.mark.parametrize("version", [2, 3])
def test_every_bundled_fmu_carries_the_windows_dll_beside_the_linux_so(windows_build, version, tmp_path):
    folder = FMU_DIR / "fmi3" if version == 3 else FMU_DIR
    platforms = ["linux", "windows"]
    if version == 3 and (BUILD_DIR / "aarch64-linux" / "platcheck").exists():
        platforms.append("aarch64")
    for model in MODELS:
        names = zipfile.ZipFile(folder / f"{model}.fmu").namelist()
        expected = [f"binaries/{platcheck.FOLDERS[p][version]}/{model}{platcheck.SUFFIX[p]}" for p in platforms]
        linux, windows = expected[:2]
        assert sorted(n for n in names if n.startswith("binaries/") and not n.endswith("/")) == sorted(expected)
        z = zipfile.ZipFile(folder / f"{model}.fmu")
        (tmp_path / "m.dll").write_bytes(z.read(windows))
        (tmp_path / "m.so").write_bytes(z.read(linux))
        if shutil.which("x86_64-w64-mingw32-objdump"):
            # Undecorated FMI names, exactly the .so's; nothing to import but Windows itself.
            assert sorted(_pe_table(tmp_path / "m.dll", "exports")) == sorted(_so_exports(tmp_path / "m.so"))
            assert set(_pe_table(tmp_path / "m.dll", "imports")) <= WINDOWS_DLLS, model


def test_the_documentation_names_the_platforms(windows_build):
    for path, folders in ((FMU_DIR / "Pendulum.fmu", ("linux64", "win64")),
                          (FMU_DIR / "fmi3" / "Pendulum.fmu", ("x86_64-linux", "x86_64-windows"))):
        page = zipfile.ZipFile(path).read("documentation/index.html").decode()
        section = page.split("<h2>Platforms</h2>", 1)[1].split("<h2>", 1)[0]
        for folder in folders:
            assert f"binaries/{folder}/Pendulum." in section, (path, folder)


def test_fmpy_validate_finds_nothing_in_the_fmus_with_windows_binaries(windows_build):
    from fmpy.validation import validate_fmu

    for path in platcheck.bundled_fmus(FMU_DIR):
        assert validate_fmu(str(path)) == [], path


@pytest.fixture(scope="module")
def report(windows_build, tmp_path_factory):
    _needs("wine", shutil.which("wine") is not None)
    return platcheck.check(FMU_DIR, BUILD_DIR, tmp_path_factory.mktemp("platcheck"))


def test_the_harness_ran_every_bundled_fmu_on_both_platforms(report):
    assert [f.label for f in report.fmus] == MODELS + [f"fmi3/{m}" for m in MODELS]
    assert report.native.precision == 0 and report.wine64.precision == 64 and report.wine53.precision == 53
    for out in (report.native, report.wine64, report.wine53):
        assert [r.end for r in out.runs] == ["ok"] * len(report.fmus)
        assert all(len(r.points) > 1 for r in out.runs)


@pytest.mark.parametrize("precision", [64, 53])
def test_the_dlls_give_the_linux_numbers_but_for_the_c_librarys_last_bits(report, precision):
    wine = report.wine64 if precision == 64 else report.wine53
    libm = platcheck.libm_differences(report.libm_native, report.libm_wine)
    libm_differs = any(differ for _, differ, _ in libm.values())
    for f, d in zip(report.fmus, report.differences(wine)):
        if d.identical:
            continue
        # Not the bits: only where the C libraries differ, and only within the
        # accuracy the model's integrator is asked for.
        assert libm_differs, f"{d.label} differs ({d.first}) though the C libraries agree"
        assert f.rtol is not None, f"{d.label} has no integrator tolerance but differs: {d.first}"
        assert d.max_scaled <= f.rtol, (d.label, d.first, d.max_scaled, d.worst)


def test_the_x87_precision_of_the_host_changes_no_bit(report):
    """mingw-w64's math runs partly on the x87 unit; an MSVC-built importer
    has it at 53 bits, mingw-w64's start-up code at 64."""
    for f, a, b in zip(report.fmus, report.wine64.runs, report.wine53.runs):
        assert np.array_equal(a.points.view(np.uint64), b.points.view(np.uint64)), f.label


def test_the_c_library_probe_draws_the_same_arguments_on_both_platforms(report):
    libm = platcheck.libm_differences(report.libm_native, report.libm_wine)
    assert set(libm) == set(platcheck.LIBM_FUNCTIONS)
    assert all(n == platcheck.LIBM_ARGUMENTS for n, _, _ in libm.values())
    # mingw-w64's own functions, linked into the DLLs, and glibc's differ in
    # the last bit at most. j1 is the one the DLLs import (from msvcrt.dll:
    # wine's here, Microsoft's on Windows), so it is reported, not bounded.
    assert all(most <= 1 for fn, (_, _, most) in libm.items() if fn != "j1"), libm


@pytest.fixture(scope="module")
def aarch64_report(aarch64_build, tmp_path_factory):
    _needs("qemu-user", shutil.which("qemu-aarch64") is not None)
    return platcheck.check_aarch64(FMU_DIR, BUILD_DIR, tmp_path_factory.mktemp("platcheck-arm"))


def test_the_fmi3_fmus_carry_an_aarch64_linux_so(aarch64_build):
    for model in MODELS:
        names = zipfile.ZipFile(FMU_DIR / "fmi3" / f"{model}.fmu").namelist()
        assert f"binaries/aarch64-linux/{model}.so" in names, model


def test_the_aarch64_so_gives_the_x86_64_numbers(aarch64_report):
    """No fused multiply-add on Arm (-ffp-contract=off, cmake/cross.cmake):
    the same glibc on both, so the same bits but where glibc's functions
    themselves differ between the two (the probe: j1)."""
    assert [f.label for f in aarch64_report.fmus] == [f"fmi3/{m}" for m in MODELS]
    assert [r.end for r in aarch64_report.qemu.runs] == ["ok"] * len(MODELS)
    libm = platcheck.libm_differences(aarch64_report.libm_native, aarch64_report.libm_qemu)
    for f, d in zip(aarch64_report.fmus, aarch64_report.differences()):
        if not d.identical:
            assert any(differ for _, differ, _ in libm.values()), f"{d.label} differs ({d.first}) though glibc agrees"
            assert f.rtol is not None and d.max_scaled <= f.rtol, (d.label, d.first, d.max_scaled)
