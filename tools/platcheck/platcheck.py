"""The bundled FMUs' binaries of two platforms, run by the same harness
(harness.c, built for each) over each FMU's default experiment, compared
point by point: the Linux .so natively, the Windows DLL under wine, and
the FMI 3.0 FMUs' aarch64-linux .so under qemu-user where built.

    python tools/platcheck/platcheck.py [--fmus DIR] [--build DIR]

prints one line per FMU (bit-identical, or where and by how much it
differs) and the C library probe (how often each math function's result
differs between the platforms). tests/test_platforms.py asserts on the
same comparison.
"""

from __future__ import annotations

import argparse
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

# binaries/ folder names of each FMI version (FMI 2.0 Sec. 2.3, FMI 3.0 Sec. 2.5.1)
FOLDERS = {"linux": {2: "linux64", 3: "x86_64-linux"}, "windows": {2: "win64", 3: "x86_64-windows"},
           "aarch64": {3: "aarch64-linux"}}
SUFFIX = {"linux": ".so", "windows": ".dll", "aarch64": ".so"}
AARCH64_ROOT = "/usr/aarch64-linux-gnu"  # Debian's libc6-arm64-cross, for qemu-aarch64 -L
LIBM_ARGUMENTS = 20000  # per function
LIBM_FUNCTIONS = ("sin", "cos", "exp", "log", "pow0.2", "pow0.125", "pow1.5", "j1")  # harness.c's probe


@dataclass
class Fmu:
    path: Path
    version: int  # 2 or 3
    identifier: str
    token: str
    start: float
    stop: float
    step: float
    tolerance: float  # 0: none given
    names: list[str]
    vrs: list[int]
    rtol: float | None  # the integrator's relative tolerance parameter, if the model has one

    @property
    def label(self) -> str:
        return f"{'fmi3/' if self.version == 3 else ''}{self.identifier}"


def bundled_fmus(fmu_dir: Path) -> list[Path]:
    return sorted(fmu_dir.glob("*.fmu")) + sorted((fmu_dir / "fmi3").glob("*.fmu"))


def describe(path: Path) -> Fmu:
    from fmpy import read_model_description

    md = read_model_description(str(path))
    version = 3 if md.fmiVersion.startswith("3") else 2
    real = ("Float64",) if version == 3 else ("Real",)
    outs = [v for v in md.modelVariables if v.causality == "output" and v.type in real]
    exp = md.defaultExperiment
    rtol = next((float(v.start) for v in md.modelVariables if v.name == "rtol" and v.start is not None), None)
    cs = md.coSimulation
    return Fmu(path, version, cs.modelIdentifier, md.instantiationToken if version == 3 else md.guid,
               float(exp.startTime or 0.0), float(exp.stopTime), float(exp.stepSize),
               float(exp.tolerance or 0.0), [v.name for v in outs], [v.valueReference for v in outs], rtol)


def _bits(x: float) -> str:
    return struct.pack(">d", x).hex()


def unpack_binaries(fmus: list[Fmu], platform: str, into: Path) -> list[str]:
    """Each FMU's binary for the platform, as into/<label>/<Name><suffix>;
    the paths relative to into."""
    rel = []
    for f in fmus:
        member = f"binaries/{FOLDERS[platform][f.version]}/{f.identifier}{SUFFIX[platform]}"
        target = into / f.label / f"{f.identifier}{SUFFIX[platform]}"
        target.parent.mkdir(parents=True, exist_ok=True)
        with zipfile.ZipFile(f.path) as z:
            target.write_bytes(z.read(member))
        rel.append(target.relative_to(into).as_posix())
    return rel


def write_jobs(fmus: list[Fmu], libraries: list[str], path: Path, resource_uri: str) -> None:
    lines = []
    for f, lib in zip(fmus, libraries):
        uri = resource_uri if f.version == 2 else ""
        lines.append("\t".join([str(f.version), lib, f.token, uri, _bits(f.start), _bits(f.stop), _bits(f.step),
                                _bits(f.tolerance), ",".join(map(str, f.vrs))]))
    path.write_text("\n".join(lines) + "\n")


@dataclass
class Run:
    library: str
    end: str
    points: np.ndarray  # rows: t, outputs...; float64


@dataclass
class Output:
    precision: int  # x87 precision control in force (0: not x87)
    runs: list[Run] = field(default_factory=list)
    libm: dict[str, np.ndarray] = field(default_factory=dict)  # function -> rows (x, f(x)) as uint64


def parse(text: str) -> Output:
    lines = text.splitlines()
    if not lines or not lines[0].startswith("x87 precision "):
        raise ValueError(f"platcheck printed no header: {text[:200]!r}")
    out = Output(int(lines[0].split()[-1]))
    rows: list[list[int]] = []
    libm: dict[str, list[list[int]]] = {}
    for line in lines[1:]:
        head, _, rest = line.partition(" ")
        if head == "run":
            lib = rest.split(" ", 1)[1]
            rows = []
        elif head == "end":
            pts = np.array(rows, dtype=np.uint64).view(np.float64) if rows else np.zeros((0, 0))
            out.runs.append(Run(lib, rest, pts))
        elif head in LIBM_FUNCTIONS:
            libm.setdefault(head, []).append([int(x, 16) for x in rest.split()])
        else:
            rows.append([int(x, 16) for x in line.split()])
    out.libm = {k: np.array(v, dtype=np.uint64) for k, v in libm.items()}
    return out


def run_native(harness: Path, args: list[str], cwd: Path) -> Output:
    p = subprocess.run([str(harness), *args], cwd=cwd, capture_output=True, text=True, timeout=600)
    if p.returncode not in (0, 1):
        raise RuntimeError(f"{harness} {' '.join(args)}: exit {p.returncode}: {p.stderr[-2000:]}")
    return parse(p.stdout)


def wine_env(prefix: Path) -> dict[str, str]:
    env = dict(os.environ)
    env.update(WINEPREFIX=str(prefix), WINEDEBUG="-all", WINEDLLOVERRIDES="mscoree,mshtml=")
    env.pop("DISPLAY", None)  # no window, no prompt to install Mono or Gecko
    return env


def run_wine(harness_exe: Path, args: list[str], cwd: Path, prefix: Path) -> Output:
    p = subprocess.run(["wine", str(harness_exe), *args], cwd=cwd, env=wine_env(prefix), capture_output=True,
                       text=True, timeout=900)
    if p.returncode not in (0, 1):
        raise RuntimeError(f"wine {harness_exe.name} {' '.join(args)}: exit {p.returncode}: {p.stderr[-2000:]}")
    return parse(p.stdout)


def stop_wineserver(prefix: Path) -> None:
    if shutil.which("wineserver"):
        subprocess.run(["wineserver", "-k"], env=wine_env(prefix), capture_output=True, timeout=60)


@dataclass
class Difference:
    label: str
    identical: bool
    points: int
    first: str = ""  # the first differing point and output
    max_scaled: float = 0.0  # max |a - b| / max |a| over the run, over the outputs
    max_ulps: int = 0
    worst: str = ""  # the output of max_scaled


def ulps(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance in units in the last place, as integers (doubles of one
    sign are ordered as their bits; a sign change counts as the largest)."""
    ia, ib = np.ascontiguousarray(a).view(np.int64), np.ascontiguousarray(b).view(np.int64)
    same_sign = (ia < 0) == (ib < 0)
    return np.where(same_sign, np.abs(ia - np.where(same_sign, ib, ia)), np.iinfo(np.int64).max)


def compare(f: Fmu, a: Run, b: Run) -> Difference:
    if a.end != "ok" or b.end != "ok":
        raise AssertionError(f"{f.label}: runs ended '{a.end}' and '{b.end}'")
    if a.points.shape != b.points.shape:
        raise AssertionError(f"{f.label}: {a.points.shape} and {b.points.shape} points")
    if not np.array_equal(a.points[:, 0].view(np.uint64), b.points[:, 0].view(np.uint64)):
        raise AssertionError(f"{f.label}: the communication points differ")
    va, vb = a.points[:, 1:], b.points[:, 1:]
    same = va.view(np.uint64) == vb.view(np.uint64)
    d = Difference(f.label, bool(same.all()), len(a.points))
    if d.identical:
        return d
    i, j = np.argwhere(~same)[0]
    d.first = f"t = {a.points[i, 0]:.17g} s, {f.names[j]}: {float(va[i, j])!r} and {float(vb[i, j])!r}"
    scale = np.maximum(np.abs(va).max(axis=0), np.finfo(float).tiny)
    scaled = (np.abs(va - vb) / scale).max(axis=0)
    k = int(np.argmax(scaled))
    d.max_scaled, d.worst = float(scaled[k]), f.names[k]
    d.max_ulps = int(ulps(va[~same], vb[~same]).max())
    return d


def libm_differences(a: Output, b: Output) -> dict[str, tuple[int, int, int]]:
    """Per function: (arguments, results that differ, the largest distance in ulps)."""
    out = {}
    for fn, rows in a.libm.items():
        other = b.libm[fn]
        assert np.array_equal(rows[:, 0], other[:, 0]), f"{fn}: the platforms drew other arguments"
        ya, yb = rows[:, 1].view(np.float64), other[:, 1].view(np.float64)
        differ = rows[:, 1] != other[:, 1]
        out[fn] = (len(rows), int(differ.sum()), int(ulps(ya[differ], yb[differ]).max()) if differ.any() else 0)
    return out


@dataclass
class Report:
    fmus: list[Fmu]
    native: Output
    wine64: Output  # x87 precision 64, as mingw-w64's start-up leaves it
    wine53: Output  # x87 precision 53, as an MSVC-built importer has it
    libm_native: Output
    libm_wine: Output

    def differences(self, wine: Output) -> list[Difference]:
        return [compare(f, a, b) for f, a, b in zip(self.fmus, self.native.runs, wine.runs)]


def check(fmu_dir: Path, build_dir: Path, work: Path) -> Report:
    fmus = [describe(p) for p in bundled_fmus(fmu_dir)]
    native_dir, win_dir, prefix = work / "linux", work / "windows", work / "wineprefix"
    libs = unpack_binaries(fmus, "linux", native_dir)
    write_jobs(fmus, [str(native_dir / lib) for lib in libs], native_dir / "jobs.txt", native_dir.as_uri() + "/")
    dlls = unpack_binaries(fmus, "windows", win_dir)
    # The DLLs by paths relative to the harness's folder: no path mapping.
    write_jobs(fmus, dlls, win_dir / "jobs.txt", "file:///Z:" + win_dir.as_posix() + "/")
    harness, harness_exe = build_dir / "platcheck", build_dir / "x86_64-windows" / "platcheck.exe"
    try:
        n = str(LIBM_ARGUMENTS)
        return Report(fmus, run_native(harness, ["jobs.txt"], native_dir),
                      run_wine(harness_exe, ["jobs.txt"], win_dir, prefix),
                      run_wine(harness_exe, ["--x87-53", "jobs.txt"], win_dir, prefix),
                      run_native(harness, ["--libm", n], native_dir),
                      run_wine(harness_exe, ["--libm", n], win_dir, prefix))
    finally:
        stop_wineserver(prefix)


@dataclass
class Aarch64Report:
    fmus: list[Fmu]  # the FMI 3.0 ones
    native: Output
    qemu: Output
    libm_native: Output
    libm_qemu: Output

    def differences(self) -> list[Difference]:
        return [compare(f, a, b) for f, a, b in zip(self.fmus, self.native.runs, self.qemu.runs)]


def run_qemu(harness: Path, args: list[str], cwd: Path) -> Output:
    p = subprocess.run(["qemu-aarch64", "-L", AARCH64_ROOT, str(harness), *args], cwd=cwd, capture_output=True,
                       text=True, timeout=900)
    if p.returncode not in (0, 1):
        raise RuntimeError(f"qemu-aarch64 {harness.name} {' '.join(args)}: exit {p.returncode}: {p.stderr[-2000:]}")
    return parse(p.stdout)


def check_aarch64(fmu_dir: Path, build_dir: Path, work: Path) -> Aarch64Report:
    fmus = [f for f in (describe(p) for p in bundled_fmus(fmu_dir)) if f.version == 3]
    native_dir, arm_dir = work / "linux3", work / "aarch64"
    for platform, folder in (("linux", native_dir), ("aarch64", arm_dir)):
        libs = unpack_binaries(fmus, platform, folder)
        write_jobs(fmus, [str(folder / lib) for lib in libs], folder / "jobs.txt", "")
    harness, harness_arm = build_dir / "platcheck", build_dir / "aarch64-linux" / "platcheck"
    n = str(LIBM_ARGUMENTS)
    return Aarch64Report(fmus, run_native(harness, ["jobs.txt"], native_dir), run_qemu(harness_arm, ["jobs.txt"], arm_dir),
                         run_native(harness, ["--libm", n], native_dir), run_qemu(harness_arm, ["--libm", n], arm_dir))


def main(argv: list[str] | None = None) -> int:
    root = Path(__file__).resolve().parents[2]
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fmus", type=Path, default=root / "fmus")
    ap.add_argument("--build", type=Path, default=root / "build")
    a = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="platcheck-") as tmp:
        r = check(a.fmus, a.build, Path(tmp))
        arm = check_aarch64(a.fmus, a.build, Path(tmp)) if (a.build / "aarch64-linux" / "platcheck").exists() else None
    for name, wine in (("x87 precision 64", r.wine64), ("x87 precision 53", r.wine53)):
        print(f"Windows DLLs under wine ({name}) against the Linux .so:")
        for d in r.differences(wine):
            if d.identical:
                print(f"  {d.label}: {d.points} points, bit-identical")
            else:
                print(f"  {d.label}: {d.points} points; first difference at {d.first}; largest "
                      f"{d.max_scaled:.3g} of the output's largest magnitude ({d.worst}), {d.max_ulps} ulps")
    print(f"C library, {LIBM_ARGUMENTS} arguments per function (mingw-w64's, in the DLLs, against glibc's):")
    for fn, (n, differ, most) in libm_differences(r.libm_native, r.libm_wine).items():
        print(f"  {fn}: {differ} results differ" + (f", by at most {most} ulps" if differ else ""))
    if arm:
        print("aarch64-linux .so under qemu-user against the x86_64-linux .so (FMI 3.0):")
        for d in arm.differences():
            print(f"  {d.label}: {d.points} points, " + ("bit-identical" if d.identical else
                  f"first difference at {d.first}; largest {d.max_scaled:.3g} ({d.worst}), {d.max_ulps} ulps"))
        print(f"C library, {LIBM_ARGUMENTS} arguments per function (glibc on aarch64 against glibc on x86-64):")
        for fn, (n, differ, most) in libm_differences(arm.libm_native, arm.libm_qemu).items():
            print(f"  {fn}: {differ} results differ" + (f", by at most {most} ulps" if differ else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
