"""Cost of the Pendulum FMU per simulated period (a benchmark, not a test).

Free pendulum, Q = 1000, 10 deg, L = 1 m, rtol = 1e-10 (atol 1e-12): wall
time of many periods through the raw C fmi2DoStep (fmpy's ctypes bindings,
no status checks in the loop), with one period per communication step and
with T/100, median of several repeats.

The internal Runge-Kutta steps per period are counted by replaying the FMU's
do_step (a fresh integrator per communication step, the step-size suggestion
carried over, the pair the FMU picks at this rtol) with libcw_rk_probe.so and
the same right-hand side in Python; the right-hand sides include the dense
output at ticks and turning points and the two polishing steps of each tick. The replay is checked to end on the FMU's
state bit for bit, so the counts are the FMU's own.

    CW_FMU_DIR=fmus CW_BUILD_DIR=build python benchmarks/bench_pendulum.py [--repeats 7]
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "tests" / "fmu"), str(ROOT / "tests")]

from fmu_driver import OK, Instance, find_fmu  # noqa: E402

G, L, M, Q = 9.81, 1.0, 1.0, 1000.0
A = math.radians(10.0)
RTOL, ATOL = 1e-10, 1e-12
PARAMS = dict(L=L, m=M, g=G, Q=Q, phi_start=A, rtol=RTOL, atol=ATOL)


def agm(a, b):
    for _ in range(40):
        a, b = 0.5 * (a + b), math.sqrt(a * b)
    return a


PERIOD = 2 * math.pi * math.sqrt(L / G) / agm(1.0, math.cos(A / 2))  # undamped; Q shifts it by 3e-8


def time_fmu(h: float, periods: int) -> tuple[float, tuple[float, float]]:
    """Seconds of wall time for `periods` periods in steps of h; final (phi, w)."""
    n = round(periods * PERIOD / h)
    with Instance(find_fmu("Pendulum"), PARAMS) as p:
        do_step, c = p.raw.fmi2DoStep, p.c
        tc = 0.0
        start = time.perf_counter()
        for _ in range(n):
            if do_step(c, tc, h, 1) != OK:
                raise RuntimeError(p.log_text())
            tc += h
        elapsed = time.perf_counter() - start
        return elapsed, tuple(p.get_many(["phi", "w"]))


def pendulum_observer(rkt, lib, method, prob):
    """A cw_rk observer that evaluates the right-hand sides the Pendulum's
    observer (observe_step) does: the dense output at a tick or a turning
    point, and a tick's two polishing steps (tests/fmu/test_rk.py's probe)."""
    out, xs = rkt.Vec(), rkt.Vec()

    def observe(ctx, rk):
        r = rk.contents
        ticked = r.x0[0] < 0.0 <= r.x1[0]
        if ticked or (r.x0[1] > 0.0 >= r.x1[1]) or (r.x0[1] < 0.0 <= r.x1[1]):
            lib.cw_rk_dense(rk, r.t0 + 0.5 * r.h, out)
        if ticked:
            x0 = rkt.Vec(r.x0[0], r.x0[1])
            for _ in range(2):
                lib.cw_rk_single_step_with(method, 2, prob.c, None, r.t0, x0, 0.5 * r.h, xs)
        return 0

    return rkt.OBSERVER(observe)


def count_rk_steps(h: float, periods: int):
    """Replay of the FMU's integration: (accepted, rejected, rhs calls, final x)."""
    import test_rk as rkt

    build = Path(os.environ.get("CW_BUILD_DIR", ROOT / "build"))
    lib = rkt.load_probe(build / "libcw_rk_probe.so")
    gamma = math.sqrt(G / L) / Q
    inertia = M * L * L

    def f(t, x):
        # model.c's acceleration() with zero torques and g_factor = 1
        return [x[1], -(G * 1.0 / L) * math.sin(x[0]) - gamma * x[1] + 0.0 / inertia]

    prob = rkt.Problem(2, f)
    # The pair the FMU picks (its `integrator` = 0: by the tolerance, DOP853 at 1e-10).
    method = lib.cw_rk_choose(0, RTOL)
    obs = pendulum_observer(rkt, lib, method, prob)
    x, t, h_next = [A, 0.0], 0.0, 0.0
    acc = rej = 0
    for _ in range(round(periods * PERIOD / h)):
        res, t_new, x_new, h_next, rk = rkt.advance(lib, prob, x, t, t + h, RTOL, ATOL, h_next=h_next,
                                                    method=method, observer=obs)
        assert res == rkt.OK
        acc, rej = acc + rk.n_accepted, rej + rk.n_rejected
        t, x = t_new, list(x_new)
    return acc, rej, len(prob.times), tuple(x)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--periods", type=int, default=2000, help="periods with one period per step")
    ap.add_argument("--count-periods", type=int, default=20, help="periods replayed to count RK steps")
    args = ap.parse_args(argv)

    print("$ " + " ".join([os.path.relpath(sys.argv[0], Path.cwd())] + (argv or sys.argv[1:])))
    print(f"Pendulum.fmu from {find_fmu('Pendulum').parent}; free pendulum, Q = {Q:g}, "
          f"A = 10 deg, L = {L:g} m, rtol = {RTOL:g}, atol = {ATOL:g}, T = {PERIOD:.6f} s; "
          f"median of {args.repeats} repeats")
    cases = [("T", PERIOD, args.periods), ("T/100", PERIOD / 100, max(1, args.periods // 20))]
    rows = []
    for label, h, periods in cases:
        runs = [time_fmu(h, periods) for _ in range(args.repeats)]
        wall = statistics.median(r[0] for r in runs)
        steps_per_period = PERIOD / h
        acc, rej, rhs, x_replay = count_rk_steps(h, args.count_periods)
        _, x_fmu = time_fmu(h, args.count_periods)
        rows.append((label, periods, 1e6 * wall / periods, 1e6 * wall / (periods * steps_per_period),
                     acc / args.count_periods, rej / args.count_periods, rhs / args.count_periods,
                     "yes" if x_replay == x_fmu else "NO"))
    head = ("comm step", "periods", "us/period", "us/doStep", "RK steps/period",
            "rejected/period", "rhs calls/period", "replay == FMU")
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for label, periods, us_p, us_s, acc, rej, rhs, same in rows:
        print(f"| {label} | {periods} | {us_p:.1f} | {us_s:.2f} | {acc:.1f} | {rej:.2f} | {rhs:.1f} | {same} |")


if __name__ == "__main__":
    main()
