"""Master overhead per FMU per communication step (a benchmark, not a test).

Runs the Pendulum + GrasshopperEscapement clock with a fixed step of 1 ms,
three ways, side by side in one process, and prints medians of R repeats:

1. fmpy's convenience calls (FMU2Slave.doStep/getReal/setReal);
2. raw ctypes calls with preallocated arrays and no logic beyond the data
   flow: the floor for any Python master on these FMUs;
3. the same calls from C (benchmarks/raw_fmi_loop.c, built here with the
   system's C compiler): the floor for any master, the FMUs' own work;
4. clockwork's master on each engine (master.engine = "python", the
   reference loop, and "compiled", the C stepping core), event location
   off, then on.

The time spent inside the FMUs is the same in all; the difference between
a master and the C floor is what the master's own logic costs.

    python benchmarks/bench_master.py [--steps 20000] [--repeats 7]
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import tempfile
import time
from ctypes import c_double, c_uint
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from fmpy import extract, read_model_description  # noqa: E402
from fmpy.fmi2 import FMU2Slave  # noqa: E402

from clockwork.engine import MasterSettings  # noqa: E402
from clockwork.engine import System
from clockwork.fmi.description import resolve_fmu as fmu_path  # noqa: E402

LINKS = ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w",
         "escapement.tau -> pendulum.tau_escapement"]
PEND = {"phi_start": math.radians(5.0), "Q": 1000.0}
ESC = {"torque": 0.004, "phi_r": math.radians(2.0)}


# fmpy's extract() leaves its folders behind: unzip under one removed at exit.
_UNZIP = tempfile.TemporaryDirectory(prefix="bench_master.")


def _slaves():
    out = []
    for name, params in (("Pendulum", PEND), ("GrasshopperEscapement", ESC)):
        path = str(fmu_path(name))
        md = read_model_description(path)
        unzipped = extract(path, unzipdir=tempfile.mkdtemp(dir=_UNZIP.name))
        s = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
        s.instantiate()
        s.setupExperiment(startTime=0.0)
        vr = {v.name: v.valueReference for v in md.modelVariables}
        s.setReal([vr[k] for k in params], list(params.values()))
        s.enterInitializationMode()
        out.append((s, vr))
    (p, pv), (e, ev) = out
    e.setReal([ev["phi"], ev["w"]], p.getReal([pv["phi"], pv["w"]]))
    p.exitInitializationMode()
    e.exitInitializationMode()
    return (p, pv), (e, ev)


def fmpy_convenience(steps: int, h: float) -> float:
    (p, pv), (e, ev) = _slaves()
    pin, pout = [pv["tau_escapement"]], [pv["phi"], pv["w"]]
    ein, eout = [ev["phi"], ev["w"]], [ev["tau"]]
    t = 0.0
    t0 = time.perf_counter()
    for k in range(steps):
        e.doStep(t, h)
        p.doStep(t, h)
        t = (k + 1) * h
        e.setReal(ein, p.getReal(pout))
        p.setReal(pin, e.getReal(eout))
    dt = time.perf_counter() - t0
    for s in (p, e):
        s.terminate()
        s.freeInstance()
    return dt


def raw_ctypes(steps: int, h: float) -> float:
    (p, pv), (e, ev) = _slaves()
    dostep_p, dostep_e = p.dll.fmi2DoStep, e.dll.fmi2DoStep
    for f in (dostep_p, dostep_e):
        f.argtypes = [p.dll.fmi2DoStep.argtypes[0] if p.dll.fmi2DoStep.argtypes else None]
    from ctypes import c_int, c_void_p, POINTER, c_size_t
    for lib in (p.dll, e.dll):
        lib.fmi2DoStep.argtypes = [c_void_p, c_double, c_double, c_int]
        lib.fmi2GetReal.argtypes = lib.fmi2SetReal.argtypes = [c_void_p, POINTER(c_uint), c_size_t, POINTER(c_double)]
    pc, ec = p.component, e.component
    pout_vr = (c_uint * 2)(pv["phi"], pv["w"])
    pin_vr = (c_uint * 1)(pv["tau_escapement"])
    ein_vr = (c_uint * 2)(ev["phi"], ev["w"])
    eout_vr = (c_uint * 1)(ev["tau"])
    buf2 = (c_double * 2)()
    buf1 = (c_double * 1)()
    pg, ps, es, eg = p.dll.fmi2GetReal, p.dll.fmi2SetReal, e.dll.fmi2SetReal, e.dll.fmi2GetReal
    pd, ed = p.dll.fmi2DoStep, e.dll.fmi2DoStep
    t = 0.0
    t0 = time.perf_counter()
    for k in range(steps):
        ed(ec, t, h, 0)
        pd(pc, t, h, 0)
        t = (k + 1) * h
        pg(pc, pout_vr, 2, buf2)
        es(ec, ein_vr, 2, buf2)
        eg(ec, eout_vr, 1, buf1)
        ps(pc, pin_vr, 1, buf1)
    dt = time.perf_counter() - t0
    for s in (p, e):
        s.terminate()
        s.freeInstance()
    return dt


def raw_c(steps: int, h: float) -> float:
    import ctypes
    import shutil
    import subprocess

    cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if cc is None:
        raise SystemExit("bench_master: no C compiler (cc, gcc or clang) for the C floor")
    lib_path = Path(_UNZIP.name) / "raw_fmi_loop.so"
    if not lib_path.exists():
        subprocess.run([cc, "-O2", "-shared", "-fPIC", "-o", str(lib_path),
                        str(ROOT / "benchmarks" / "raw_fmi_loop.c")], check=True)
    lib = ctypes.CDLL(str(lib_path))
    (p, pv), (e, ev) = _slaves()
    fn = lambda dll, name: ctypes.cast(getattr(dll, name), ctypes.c_void_p)  # noqa: E731
    args = [ctypes.c_void_p(p.component), ctypes.c_void_p(e.component),
            fn(p.dll, "fmi2DoStep"), fn(e.dll, "fmi2DoStep"), fn(p.dll, "fmi2GetReal"), fn(p.dll, "fmi2SetReal"),
            fn(e.dll, "fmi2GetReal"), fn(e.dll, "fmi2SetReal"),
            (c_uint * 2)(pv["phi"], pv["w"]), (c_uint * 1)(pv["tau_escapement"]),
            (c_uint * 2)(ev["phi"], ev["w"]), (c_uint * 1)(ev["tau"]), ctypes.c_long(steps), c_double(h)]
    t0 = time.perf_counter()
    rc = lib.raw_fmi_loop(*args)
    dt = time.perf_counter() - t0
    if rc:
        raise SystemExit("bench_master: an FMU refused a call in the C floor loop")
    for s in (p, e):
        s.terminate()
        s.freeInstance()
    return dt


def clockwork_master(steps: int, h: float, events: bool, engine: str) -> float:
    with System({"pendulum": ("Pendulum", PEND), "escapement": ("GrasshopperEscapement", ESC)}, LINKS,
                MasterSettings(step=h, event_location=events, engine=engine)) as s:
        t0 = time.perf_counter()
        s.master.run_until(steps * h)
        dt = time.perf_counter() - t0
        n = s.master.stats.steps
    return dt * steps / n  # located events add steps; normalize to the grid


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--step-size", type=float, default=1e-3, help="communication step, s")
    ap.add_argument("--only", nargs="+", metavar="WORD",
                    help="run only the configurations whose name holds one of these words "
                         "(e.g. --only 'raw C' for the FMUs' own work, the run to profile with callgrind)")
    a = ap.parse_args(argv)
    runs = {
        "fmpy FMU2Slave calls": lambda: fmpy_convenience(a.steps, a.step_size),
        "raw ctypes (floor)": lambda: raw_ctypes(a.steps, a.step_size),
        "raw C calls (floor)": lambda: raw_c(a.steps, a.step_size),
        **{f"clockwork {e} engine, events {'on' if ev else 'off'}":
           (lambda e=e, ev=ev: clockwork_master(a.steps, a.step_size, ev, e))
           for e in ("python", "compiled") for ev in (False, True)},
    }
    if a.only:
        runs = {k: f for k, f in runs.items() if any(w in k for w in a.only)}
        if not runs:
            raise SystemExit(f"bench_master: no configuration matches {a.only}")
    samples = {k: [] for k in runs}
    for _ in range(a.repeats):  # interleaved, so that machine noise hits all alike
        for k, f in runs.items():
            samples[k].append(f() / a.steps * 1e6)
    floor = statistics.median(samples.get("raw ctypes (floor)", [math.nan]))
    c_floor = statistics.median(samples.get("raw C calls (floor)", [math.nan]))
    print(f"# {a.steps} steps of {a.step_size} s, 2 FMUs, median of {a.repeats} (us)")
    print("| configuration | per step | per FMU-step | above raw ctypes, per FMU-step | above raw C, per FMU-step |")
    print("|---|---|---|---|---|")
    for k, v in samples.items():
        med = statistics.median(v)
        print(f"| {k} | {med:.2f} | {med / 2:.2f} | {(med - floor) / 2:+.2f} | {(med - c_floor) / 2:+.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
