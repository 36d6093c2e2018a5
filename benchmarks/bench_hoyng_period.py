"""Where a period of Hoyng's clock goes (a benchmark, not a test).

Hoyng's clock at point C (L = g = 1, Q = 1/(2 eps), mu0 = 1.5e-5,
phi0 = 0.03) on its stationary swing, side by side in one process:

1. the Pendulum FMU alone, doStep in a loop with 7 steps per period: the
   FMU's own integration work at the scene's rtol 1e-10;
2. Pendulum + GrasshopperEscapement under a bare ``run_until`` with the
   scene's settings (Jacobi, 2 pi step, switches located), with the
   master's statistics per period, on each engine (master.engine =
   "python", the reference loop, and "compiled", the C stepping core).

The difference is the master's own work per period; `clockwork bench`
measures the whole `hoyng_long_run` analysis on top of it.

3. the yardstick: Hoyng's own method compiled, classical RK4 at dt = 0.03
   on the whole clock (benchmarks/hoyng_rk4.c, built with the system's C
   compiler into a temporary folder, once), run just before each case
   of each repeat: the ratios to it are printed, both to the median RK4
   and as the median of the per-repeat ratios (each run over the RK4 run
   beside it), which machine noise shifts less.

Each is run with each Runge-Kutta pair of the Pendulum (`integrator` 1 =
Dormand-Prince 5(4), 2 = DOP853; 0 = the FMU's default, chosen by rtol).
The right-hand-side evaluations per period of case 1 are counted by
replaying the FMU's do_step with libcw_rk_probe.so (in CW_BUILD_DIR,
default build/) and the same right-hand side in Python, including the dense
output and the two polishing steps of each tick; the replay is checked to
end on the FMU's state bit for bit.

4. the whole hoyng_fig6 scene's analysis in this process, on each engine
   (the Python engine for a fifth of the periods: it is slower).

5. with --fmi-versions 2 3: cases 2 and 4 on the FMI 3.0 build of the
   FMUs too (master.fmi_version = 3: the Pendulum returns early at each
   tick and turning point and the master handles the event there), and
   without early return (master.early_return = false), with the FMU state
   saves and restores per period of each.

6. --counts: only the event handling per period (steps, FMU-state saves,
   rollbacks, replays, predicted landings), event prediction off and on.

    python benchmarks/bench_hoyng_period.py [--periods 2000] [--repeats 3] [--integrators 1 2]
                                            [--scene-periods 20000] [--fmi-versions 2 3]
    python benchmarks/bench_hoyng_period.py --counts --periods 200 --fmi-versions 2 3 3-
"""

from __future__ import annotations

import argparse
import ctypes
import math
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path[1:1] = [str(ROOT / "tests" / "fmu"), str(ROOT / "tests")]

from clockwork.physics import analytic  # noqa: E402
from clockwork.engine import MasterSettings  # noqa: E402
from clockwork.engine import System  # noqa: E402

TWO_PI = 2.0 * math.pi
ENGINES = ("python", "compiled")
EPS, MU0, PHI0 = 1.167245e-4, 1.5e-5, 0.03
PEND = dict(L=1.0, g=1.0, m=1.0, Q=1.0 / (2.0 * EPS), rtol=1e-10, atol=1e-12)
LINKS = ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w",
         "escapement.tau -> pendulum.tau_escapement"]


def pendulum_alone(periods: int, integrator: int = 0) -> float:
    """us per period of the Pendulum FMU's doStep, 7 steps per period."""
    lam = analytic.hoyng_stationary_amplitude(MU0, EPS, PHI0)
    pend = dict(PEND, phi_start=lam, integrator=integrator)
    with System({"pendulum": ("Pendulum", pend)}, [], MasterSettings(step=1.0)) as s:
        inst = s.instances["pendulum"]
        do_step, comp = inst.c_doStep, inst.component
        h, t = TWO_PI / 7, 0.0
        t0 = time.perf_counter()
        for k in range(7 * periods):
            do_step(comp, t, h, 0)
            t = (k + 1) * h
        return (time.perf_counter() - t0) / periods * 1e6


def evaluations_alone(periods: int, integrator: int) -> tuple[float, float, bool]:
    """(right-hand sides, RK steps) per period of case 1, by replay, and
    whether the replay ends on the FMU's state bit for bit."""
    import test_rk as rkt
    from bench_pendulum import pendulum_observer
    from fmu_driver import Instance, find_fmu

    build = Path(os.environ.get("CW_BUILD_DIR", ROOT / "build"))
    lib = rkt.load_probe(build / "libcw_rk_probe.so")
    lam = analytic.hoyng_stationary_amplitude(MU0, EPS, PHI0)
    rtol, atol = PEND["rtol"], PEND["atol"]
    method = lib.cw_rk_choose(integrator, rtol)
    gamma = 1.0 / PEND["Q"]  # omega0 / Q with L = g = 1
    prob = rkt.Problem(2, lambda t, x: [x[1], -(1.0 * 1.0 / 1.0) * math.sin(x[0]) - gamma * x[1] + 0.0])
    obs = pendulum_observer(rkt, lib, method, prob)
    h, x, t, h_next, steps = TWO_PI / 7, [lam, 0.0], 0.0, 0.0, 0
    for k in range(7 * periods):  # as pendulum_alone: from k h to k h + h
        res, t, x_new, h_next, rk = rkt.advance(lib, prob, x, k * h, k * h + h, rtol, atol, h_next=h_next,
                                                observer=obs, method=method)
        assert res == rkt.OK
        x, steps = list(x_new), steps + rk.n_accepted + rk.n_rejected
    with Instance(find_fmu("Pendulum"), dict(PEND, phi_start=lam, integrator=integrator)) as p:
        for k in range(7 * periods):
            p.step(h, k * h)
        same = tuple(x) == tuple(p.get_many(["phi", "w"]))
    return len(prob.times) / periods, steps / periods, same


def bare_master(periods: int, integrator: int = 0, engine: str = "compiled", build: str = "2",
                prediction: bool = True) -> tuple[float, dict]:
    """us per period of Master.run_until with the scene's settings on the
    given engine (master.engine) and build ("2", "3", or "3-" for FMI 3.0
    without early return), and its statistics per period."""
    lam = analytic.hoyng_stationary_amplitude(MU0, EPS, PHI0)
    settings = MasterSettings(step=TWO_PI, order="jacobi", engine=engine, fmi_version=int(build[0]),
                              early_return=not build.endswith("-"), event_prediction=prediction)
    with System({"pendulum": ("Pendulum", dict(PEND, phi_start=lam, integrator=integrator)),
                 "escapement": ("GrasshopperEscapement", dict(torque=MU0, phi_r=PHI0))},
                LINKS, settings, record={"pendulum": ["tick_time"]}) as s:
        m = s.master
        m.run_until(50 * TWO_PI)  # past the first steps
        before = dict(vars(m.stats))
        ev = s.instances["pendulum"].events if build.startswith("3") else None
        early = ev.early_returns if ev is not None else 0
        t0 = time.perf_counter()
        m.run_until(m.t + periods * TWO_PI)
        wall = time.perf_counter() - t0
        per = {k: (v - before[k]) / periods for k, v in vars(m.stats).items()}
        if ev is not None:
            per["pendulum_early_returns"] = (ev.early_returns - early) / periods
        per["outputs"] = [s.output("pendulum", "tick_time")]
    return wall / periods * 1e6, per


def full_scene(periods: int, engine: str, build: str = "2") -> tuple[float, float]:
    """us per period of the whole hoyng_fig6 scene's analysis (hoyng_long_run:
    the co-simulation with its tick points and torque noise from the start,
    then the AveragedPendulum twins replayed), run in this process on the
    given engine: (co-simulation alone, the whole analysis)."""
    from clockwork.analyses.registry import run_analysis
    from clockwork.run.catalog import load_scene

    scene = load_scene("hoyng_fig6", [f"experiment.stop={periods * TWO_PI!r}", "escapement.noise_start=0",
                                      f"master.engine={engine}", f"master.fmi_version={build[0]}",
                                      f"master.early_return={str(not build.endswith('-')).lower()}"])
    res = run_analysis(scene, {})["result"]
    return res["wall_time_cosimulation_s"] / periods * 1e6, res["wall_time_run_s"] / periods * 1e6


_rk4_build = None  # (the temporary folder, the library): built once per process


def _rk4_library():
    """benchmarks/hoyng_rk4.c built with cc -O2 into a temporary folder
    (removed when the process ends)."""
    global _rk4_build
    if _rk4_build is None:
        import shutil
        import subprocess
        import tempfile

        cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
        if cc is None:
            raise SystemExit("bench_hoyng_period: no C compiler (cc, gcc or clang) for the RK4 yardstick")
        tmp = tempfile.TemporaryDirectory(prefix="hoyng_rk4.")
        lib_path = Path(tmp.name) / "hoyng_rk4.so"
        subprocess.run([cc, "-O2", "-shared", "-fPIC", "-o", str(lib_path), str(ROOT / "benchmarks" / "hoyng_rk4.c"),
                        "-lm"], check=True)
        lib = ctypes.CDLL(str(lib_path))
        lib.hoyng_rk4.restype = ctypes.c_long
        lib.hoyng_rk4.argtypes = [ctypes.POINTER(ctypes.c_double), ctypes.c_long] + [ctypes.c_double] * 4
        _rk4_build = (tmp, lib)
    return _rk4_build[1]


def compiled_rk4(periods: int, dt: float = 0.03) -> float:
    """us per period of benchmarks/hoyng_rk4.c (built here with cc -O2)."""
    lib = _rk4_library()
    lam = analytic.hoyng_stationary_amplitude(MU0, EPS, PHI0)
    state = (ctypes.c_double * 3)(lam, 0.0, -1.0)
    steps = round(periods * TWO_PI / dt)
    t0 = time.perf_counter()
    ticks = lib.hoyng_rk4(state, steps, dt, EPS, MU0, PHI0)
    wall = time.perf_counter() - t0
    if abs(ticks - periods) > 1:
        raise SystemExit(f"bench_hoyng_period: the RK4 clock ticked {ticks} times in {periods} periods")
    return wall / periods * 1e6


def ratio_to_rk4(runs: list[float], rk4: list[float]) -> str:
    """The median of the per-repeat ratios run / RK4, each run paired with
    the RK4 run just before it (side by side, so that machine noise hits
    both alike), with their spread."""
    ratios = [r / y for r, y in zip(runs, rk4)]
    return f"{statistics.median(ratios):.2f}x (min {min(ratios):.2f}, max {max(ratios):.2f})"


COUNTED = ("steps", "states_saved", "rollbacks", "replays", "event_iterations", "predicted_landings", "mispredicted")


def event_counts(periods: int, builds: list[str]) -> None:
    """Per period: the master's steps, FMU-state saves, restores (rollbacks
    and replays set a saved state) and predicted landings, with event
    prediction off (rollback locates the switches) and on, per build, from
    the statistics of a bare run_until on each engine (they must agree)."""
    label = {"2": "FMI 2.0", "3": "FMI 3.0, early return", "3-": "FMI 3.0, no early return"}
    print(f"| build | event_prediction | {' | '.join(COUNTED)} | engines agree |")
    print("|---|---|" + "---|" * len(COUNTED) + "---|")
    for b in builds:
        for prediction in (False, True):
            per = {e: bare_master(periods, 0, e, b, prediction)[1] for e in ENGINES}
            same = per["python"] == per["compiled"]
            print(f"| {label[b]} | {str(prediction).lower()} | "
                  + " | ".join(f"{per['compiled'][k]:.2f}" for k in COUNTED) + f" | {'yes' if same else 'NO'} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--periods", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--integrators", type=int, nargs="+", default=[1, 2],
                    help="Pendulum integrator values (0 auto, 1 DP5(4), 2 DOP853)")
    ap.add_argument("--count-periods", type=int, default=50, help="periods replayed to count evaluations")
    ap.add_argument("--scene-periods", type=int, default=20000,
                    help="periods of the whole hoyng_fig6 scene per run (0: skip it)")
    ap.add_argument("--fmi-versions", nargs="+", default=["2"], choices=["2", "3", "3-"],
                    help="builds of the FMUs: 2, 3 (FMI 3.0 with early return), 3- (FMI 3.0 without)")
    ap.add_argument("--counts", action="store_true",
                    help="only the saves, restores and predicted landings per period, prediction off and on")
    a = ap.parse_args(argv)
    if a.counts:
        event_counts(a.periods, a.fmi_versions)
        return 0
    names = {0: "auto", 1: "DP5(4)", 2: "DOP853"}
    builds = a.fmi_versions
    alone = {i: [] for i in a.integrators}
    master = {(i, e, b): [] for i in a.integrators for e in ENGINES for b in builds}
    per = {}
    rk4 = []  # every RK4 run
    beside = {}  # the RK4 run just before each case's runs, per case
    scene = {(e, b): [] for e in ENGINES for b in builds}

    def yardstick(case) -> None:
        rk4.append(compiled_rk4(max(a.periods, 20000)))
        beside.setdefault(case, []).append(rk4[-1])

    for _ in range(a.repeats):  # interleaved, so that machine noise hits all alike
        if a.scene_periods:
            for e in ENGINES:
                for b in builds:
                    yardstick(("scene", e, b))
                    scene[e, b].append(full_scene(a.scene_periods if e == "compiled"
                                                  else max(1, a.scene_periods // 5), e, b))
        for i in a.integrators:
            alone[i].append(pendulum_alone(a.periods, i))
            for e in ENGINES:
                for b in builds:
                    yardstick(("bare", i, e, b))
                    us, per[i, e, b] = bare_master(a.periods, i, e, b)
                    master[i, e, b].append(us)
    print(f"# Hoyng's clock at point C, {a.periods} periods, median of {a.repeats} (us per period)")
    yard = statistics.median(rk4)
    print(f"Compiled RK4 of the whole clock, dt = 0.03 (Hoyng's method, {round(TWO_PI / 0.03)} steps per period): "
          f"{yard:.2f} (all runs: {', '.join(f'{v:.2f}' for v in rk4)})")
    label = {"2": "FMI 2.0", "3": "FMI 3.0 with early return", "3-": "FMI 3.0 without early return"}
    for e, b in scene if a.scene_periods else ():
        cosim = statistics.median(c for c, _ in scene[e, b])
        whole = statistics.median(w for _, w in scene[e, b])
        print(f"Whole hoyng_fig6 scene (hoyng_long_run, noise from the start), {label[b]}, engine {e}: "
              f"co-simulation {cosim:.1f} "
              f"({cosim / yard:.1f}x the median RK4; median of per-repeat ratios "
              f"{ratio_to_rk4([c for c, _ in scene[e, b]], beside['scene', e, b])}), "
              f"whole analysis {whole:.1f} ({whole / yard:.1f}x; median of per-repeat ratios "
              f"{ratio_to_rk4([w for _, w in scene[e, b]], beside['scene', e, b])}; all runs: "
              f"{', '.join(f'{w:.1f}' for _, w in scene[e, b])}); 110 days (4.84e6 periods) in about "
              f"{whole * 4.84e6 / 1e6:.0f} s")
    for i in a.integrators:
        rhs, steps, same = evaluations_alone(a.count_periods, i)
        print(f"## integrator = {i} ({names[i]})")
        print(f"Pendulum FMU alone, 7 steps per period, rtol 1e-10: {statistics.median(alone[i]):.1f} "
              f"(all runs: {', '.join(f'{v:.1f}' for v in alone[i])}); "
              f"{rhs:.1f} right-hand sides and {steps:.1f} RK steps per period "
              f"(replay == FMU: {'yes' if same else 'NO'})")
        for b in builds:
            for e in ENGINES:
                us = statistics.median(master[i, e, b])
                print(f"Pendulum + GrasshopperEscapement, bare run_until, {label[b]}, engine {e}: {us:.1f} "
                      f"(all runs: {', '.join(f'{v:.1f}' for v in master[i, e, b])}); "
                      f"{us / yard:.1f}x the median compiled RK4, median of per-repeat ratios "
                      f"{ratio_to_rk4(master[i, e, b], beside['bare', i, e, b])} "
                      f"(FMU alone: {statistics.median(alone[i]) / yard:.1f}x)")
            same = per[i, "python", b] == per[i, "compiled", b]
            print(f"per period ({label[b]}): " + ", ".join(
                f"{k} {v:.2f}" for k, v in per[i, "compiled", b].items() if k != "outputs" and v)
                + f"; python and compiled engines agree on every statistic and the last tick bit for bit: "
                f"{'yes' if same else 'NO'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
