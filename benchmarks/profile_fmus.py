"""Instructions per step of the clock's FMUs, counted by callgrind (a profile, not a test).

Runs bench_master's C floor (Pendulum + GrasshopperEscapement, FMI 2.0, 1 ms
steps, the same FMI calls as one communication step and no master) as a
program of its own (benchmarks/raw_fmi_main.c) under valgrind's callgrind,
for each FMU folder given, and prints the instructions per step and the
functions they go to. Instruction counts do not depend on the load of the
machine, so two builds (e.g. this checkout's fmus/ and an earlier
commit's) compare exactly where wall times would not.

    python benchmarks/profile_fmus.py [--fmu-dir fmus /path/to/old/fmus] [--steps 20000]
                                      [--set pendulum.rho_air=1.2] [--top 15] [--no-callgrind]

The callgrind command it runs for each folder is printed; its output files
stay under --out (default out/profile_fmus/). The program is also run for 0
steps, and that count (loading, instantiation, initialization) is taken off.
"""

from __future__ import annotations

import argparse
import math
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

PEND = {"phi_start": math.radians(5.0), "Q": 1000.0}  # bench_master.py's clock
ESC = {"torque": 0.004, "phi_r": math.radians(2.0)}


def build_driver(work: Path) -> Path:
    import fmpy

    cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if cc is None:
        raise SystemExit("profile_fmus: no C compiler (cc, gcc or clang)")
    exe = work / "raw_fmi_main"
    subprocess.run([cc, "-O2", "-g", "-o", str(exe), "-I", str(Path(fmpy.__file__).parent / "c-code"),
                    str(ROOT / "benchmarks" / "raw_fmi_main.c"), str(ROOT / "benchmarks" / "raw_fmi_loop.c"),
                    "-ldl"], check=True)
    return exe


def fmu_args(fmu_dir: Path, work: Path, overrides: dict[str, dict[str, float]]) -> list[str]:
    """The driver's arguments for the Pendulum and escapement of fmu_dir."""
    from fmpy import extract, read_model_description

    out = []
    vrs = {}
    for key, name, params in (("pendulum", "Pendulum", PEND), ("escapement", "GrasshopperEscapement", ESC)):
        path = fmu_dir / f"{name}.fmu"
        md = read_model_description(str(path))
        unzipped = Path(extract(str(path), unzipdir=str(work / f"{fmu_dir.name}-{name}-{len(out)}")))
        vr = {v.name: v.valueReference for v in md.modelVariables}
        values = {**params, **overrides.get(key, {})}
        missing = [k for k in values if k not in vr]
        if missing:
            raise SystemExit(f"profile_fmus: {path} has no variable {', '.join(missing)}")
        so = unzipped / "binaries" / "linux64" / f"{md.coSimulation.modelIdentifier}.so"
        out += [str(so), md.guid, (unzipped / "resources").as_uri(),
                ",".join(f"{vr[k]}={v!r}" for k, v in values.items())]
        vrs[key] = vr
    p, e = vrs["pendulum"], vrs["escapement"]
    return out + [f"{p['phi']},{p['w']}", f"{p['tau_escapement']}", f"{e['phi']},{e['w']}", f"{e['tau']}"]


def exclusive_costs(out_file: Path) -> tuple[int, dict[tuple[str, str], int]]:
    """Total instructions and the exclusive count per (object, function) of
    a callgrind output file (its format: valgrind's callgrind manual, "Callgrind
    Format Specification"). Read here rather than by callgrind_annotate, which
    merges functions of one name across objects when no debug information
    names their files: the FMUs share the runtime's function names."""
    names = {"ob": {}, "fn": {}}
    ob = fn = ""
    costs: dict[tuple[str, str], int] = {}
    total = 0
    skip_next = False
    for line in out_file.read_text().splitlines():
        if not line:
            continue
        if skip_next:  # the cost line after calls= is the call's inclusive cost
            skip_next = False
            continue
        head = line[0]
        if head.isdigit() or head in "+-*":
            parts = line.split()
            if len(parts) > 1:
                n = int(parts[1])
                costs[(ob, fn)] = costs.get((ob, fn), 0) + n
                total += n
            continue
        key, _, value = line.partition("=")
        if key in ("ob", "fn", "cob", "cfn"):
            kind = key[-2:]
            m = re.fullmatch(r"\((\d+)\)(?: (.*))?", value)
            if m:
                if m.group(2) is not None:
                    names[kind][m.group(1)] = m.group(2)
                value = names[kind][m.group(1)]
            if key == "ob":
                ob = value
            elif key == "fn":
                fn = value
        elif key == "calls":
            skip_next = True
    return total, costs


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fmu-dir", nargs="+", type=Path, default=[ROOT / "fmus"],
                    help="FMU folders to profile (FMI 2.0 builds), side by side")
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--step-size", type=float, default=1e-3, help="communication step, s")
    ap.add_argument("--set", action="append", default=[], metavar="INSTANCE.NAME=VALUE",
                    help="a parameter of pendulum or escapement (e.g. pendulum.rho_air=1.2)")
    ap.add_argument("--top", type=int, default=15, help="functions listed per folder")
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "profile_fmus")
    ap.add_argument("--no-callgrind", action="store_true", help="time the driver instead (wall clock, noisy)")
    a = ap.parse_args(argv)
    overrides: dict[str, dict[str, float]] = {}
    for item in a.set:
        m = re.fullmatch(r"(pendulum|escapement)\.(\w+)=(.+)", item)
        if not m:
            raise SystemExit(f"profile_fmus: --set {item!r}: expected pendulum.NAME=VALUE or escapement.NAME=VALUE")
        overrides.setdefault(m.group(1), {})[m.group(2)] = float(m.group(3))
    if not a.no_callgrind and shutil.which("valgrind") is None:
        raise SystemExit("profile_fmus: valgrind is not installed (apt-get install valgrind), or use --no-callgrind")
    a.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="profile_fmus.") as tmp:
        work = Path(tmp)
        exe = build_driver(work)
        results = []
        for k, fmu_dir in enumerate(a.fmu_dir):
            args = [str(exe), str(a.steps), repr(a.step_size), *fmu_args(fmu_dir.resolve(), work, overrides)]
            if a.no_callgrind:
                t0 = time.perf_counter()
                subprocess.run(args, check=True)
                print(f"{fmu_dir}: {(time.perf_counter() - t0) / a.steps * 1e6:.3f} us per step (whole program)")
                continue
            out_file = a.out / f"callgrind.{k}.out"
            cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out_file}", *args]
            print(f"# {fmu_dir}: {' '.join(cmd[:3])} raw_fmi_main {a.steps} {a.step_size} <FMUs>", flush=True)
            subprocess.run(cmd, check=True, capture_output=True)
            # The same program for 0 steps: the count of loading and initializing, taken off.
            empty = a.out / f"callgrind.{k}.empty.out"
            subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={empty}", args[0], "0",
                            *args[2:]], check=True, capture_output=True)
            total, costs = exclusive_costs(out_file)
            base, base_costs = exclusive_costs(empty)
            per_step = (total - base) / a.steps
            results.append((fmu_dir, per_step))
            print(f"{fmu_dir}: {per_step:.1f} instructions per step "
                  f"({total:,} in all, {base:,} of them loading and initializing)")
            rows = sorted(((n - base_costs.get(k, 0), k) for k, n in costs.items()), reverse=True)
            print("| instructions per step | function | object |\n|---|---|---|")
            for n, (obj, fn) in rows[:a.top]:
                print(f"| {n / a.steps:.1f} | {fn} | {Path(obj).name} |")
        if len(results) > 1:
            first = results[0][1]
            for fmu_dir, per_step in results[1:]:
                print(f"{fmu_dir} / {results[0][0]}: {per_step / first:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
