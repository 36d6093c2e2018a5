"""Where a period of Hoyng's clock goes (a benchmark, not a test).

Hoyng's clock at point C (L = g = 1, Q = 1/(2 eps), mu0 = 1.5e-5,
phi0 = 0.03) on its stationary swing, side by side in one process:

1. the Pendulum FMU alone, doStep in a loop with 7 steps per period: the
   FMU's own integration work at the scene's rtol 1e-10;
2. Pendulum + GrasshopperEscapement under a bare ``Master.run_until`` with
   the scene's settings (Jacobi, 2 pi step, switches located), with the
   master's statistics per period.

The difference is the master's own work per period; `clockwork bench`
measures the whole `hoyng_long_run` analysis on top of it.

    python benchmarks/bench_hoyng_period.py [--periods 2000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from clockwork.physics import analytic  # noqa: E402
from clockwork.engine import MasterSettings  # noqa: E402
from clockwork.engine import System  # noqa: E402

TWO_PI = 2.0 * math.pi
EPS, MU0, PHI0 = 1.167245e-4, 1.5e-5, 0.03
PEND = dict(L=1.0, g=1.0, m=1.0, Q=1.0 / (2.0 * EPS), rtol=1e-10, atol=1e-12)
LINKS = ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w",
         "escapement.tau -> pendulum.tau_escapement"]


def pendulum_alone(periods: int) -> float:
    """us per period of the Pendulum FMU's doStep, 7 steps per period."""
    lam = analytic.hoyng_stationary_amplitude(MU0, EPS, PHI0)
    with System({"pendulum": ("Pendulum", dict(PEND, phi_start=lam))}, [], MasterSettings(step=1.0)) as s:
        inst = s.instances["pendulum"]
        do_step, comp = inst.c_doStep, inst.component
        h, t = TWO_PI / 7, 0.0
        t0 = time.perf_counter()
        for k in range(7 * periods):
            do_step(comp, t, h, 0)
            t = (k + 1) * h
        return (time.perf_counter() - t0) / periods * 1e6


def bare_master(periods: int) -> tuple[float, dict]:
    """us per period of Master.run_until with the scene's settings, and its statistics per period."""
    lam = analytic.hoyng_stationary_amplitude(MU0, EPS, PHI0)
    with System({"pendulum": ("Pendulum", dict(PEND, phi_start=lam)),
                 "escapement": ("GrasshopperEscapement", dict(torque=MU0, phi_r=PHI0))},
                LINKS, MasterSettings(step=TWO_PI, order="jacobi"), record={"pendulum": ["tick_time"]}) as s:
        m = s.master
        m.run_until(50 * TWO_PI)  # past the first steps
        before = dict(vars(m.stats))
        t0 = time.perf_counter()
        m.run_until(m.t + periods * TWO_PI)
        wall = time.perf_counter() - t0
        per = {k: (v - before[k]) / periods for k, v in vars(m.stats).items()}
    return wall / periods * 1e6, per


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--periods", type=int, default=2000)
    ap.add_argument("--repeats", type=int, default=3)
    a = ap.parse_args(argv)
    alone, master, per = [], [], {}
    for _ in range(a.repeats):  # interleaved, so that machine noise hits both alike
        alone.append(pendulum_alone(a.periods))
        us, per = bare_master(a.periods)
        master.append(us)
    print(f"# Hoyng's clock at point C, {a.periods} periods, median of {a.repeats} (us per period)")
    print(f"Pendulum FMU alone, 7 steps per period, rtol 1e-10: {statistics.median(alone):.1f}")
    print(f"Pendulum + GrasshopperEscapement, bare Master.run_until: {statistics.median(master):.1f}")
    print("per period: " + ", ".join(f"{k} {v:.2f}" for k, v in per.items() if v))
    return 0


if __name__ == "__main__":
    sys.exit(main())
