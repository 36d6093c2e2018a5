"""Ziemkiewicz Fig. 4(a) as a whole process: `clockwork run` against a
SciPy-only script doing the same figure (benchmarks/fig4a_scipy.py).

Both run as fresh processes of this interpreter, one after the other in
pairs (clockwork, script, clockwork, script, ...), each into a new output
directory, the point cache off. A pair's ratio is taken within the pair,
so that a machine whose speed drifts moves both sides alike; the median
ratio is the figure to quote. One pair first as a warm-up (file caches).

    python benchmarks/bench_fig4a_process.py --pairs 7
    python benchmarks/bench_fig4a_process.py --timeline   # where one clockwork run's time goes
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def timed(command: list[str], env: dict) -> float:
    """Wall time of a whole process, s (it must succeed)."""
    t0 = time.perf_counter()
    r = subprocess.run(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed ({r.returncode}): {r.stderr.strip()}")
    return wall


# One `clockwork run` with timestamps (s since the interpreter started) at the
# points that matter, in every process of the run (each line names its pid):
# numpy, fmpy, clockwork's run modules and matplotlib imported, the scene
# loaded, the plot process forked, the results handed to it, each plot drawn,
# the plots collected, the end. Nothing is imported ahead of the command: the
# marks come from a wrapped __import__, and the plot code is wrapped when a
# process imports it (the plot process forks before the heavy imports).
TIMELINE = r"""
import builtins, os, sys, time
def since_start():
    stat = open(f"/proc/{os.getpid()}/stat").read().rsplit(")", 1)[1].split()
    return time.clock_gettime(time.CLOCK_BOOTTIME) - int(stat[19]) / os.sysconf("SC_CLK_TCK")
start = time.clock_gettime(time.CLOCK_BOOTTIME) - since_start()
def mark(what):
    print(f"{time.clock_gettime(time.CLOCK_BOOTTIME) - start:6.3f} s  pid {os.getpid()}  {what}", file=sys.stderr)
mark("interpreter started, timeline script running")
def wrap(owner, name, before=None, after=None):
    f = getattr(owner, name)
    def w(*a, **k):
        before and mark(before(*a))
        r = f(*a, **k)
        after and mark(after(*a))
        return r
    setattr(owner, name, w)
def on_catalog(m):
    wrap(m, "load_scene", after=lambda *a: "scene loaded")
def on_background(m):
    wrap(m, "load_matplotlib", after=lambda *a: "matplotlib loaded (plot process)")
    wrap(m, "draw_plot", after=lambda *a: f"plot {a[3]} drawn")
    wrap(m._PlotProcess, "submit", before=lambda *a: "points done: results handed to the plot process")
    wrap(m._PlotProcess, "collect", after=lambda *a: "plots collected")
    if hasattr(m, "fork_child"):
        wrap(m, "fork_child", before=lambda *a: "plot process forks")
    else:  # before the plot process could start early (c438f17)
        wrap(m._PlotProcess, "__init__", before=lambda *a: "plot process forks")
WATCH = {"numpy": None, "fmpy": None, "clockwork.run.catalog": on_catalog,
         "clockwork.results.plots.background": on_background, "matplotlib.figure": None}
seen = {}
real_import = builtins.__import__
def watching_import(name, *a, **k):
    m = real_import(name, *a, **k)
    for w in [w for w in WATCH if w not in seen and w in sys.modules
              and not getattr(sys.modules[w].__spec__, "_initializing", False)]:
        seen[w] = True
        mark(f"{w} imported")
        WATCH[w] and WATCH[w](sys.modules[w])
    return m
builtins.__import__ = watching_import
from clockwork import cli
if hasattr(cli, "fork_child"):
    wrap(cli, "fork_child", before=lambda *a: "plot process forks")
code = cli.console()
mark("main() returned")
sys.exit(code)
"""


def timeline(env: dict, out: Path) -> None:
    command = [sys.executable, "-c", TIMELINE, "run", "ziemkiewicz_fig4a", "--out", str(out), "--no-progress"]
    r = subprocess.run(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    print(r.stderr, end="")
    if r.returncode != 0:
        raise SystemExit(f"the run failed ({r.returncode})")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--pairs", type=int, default=7, help="counted pairs (default 7)")
    ap.add_argument("--timeline", action="store_true", help="one clockwork run with timestamps instead")
    args = ap.parse_args()
    env = dict(os.environ, CLOCKWORK_CACHE="off")
    scratch = Path(tempfile.mkdtemp(prefix="fig4a-process."))
    try:
        if args.timeline:
            timed([sys.executable, "-m", "clockwork", "run", "ziemkiewicz_fig4a", "--out", str(scratch / "warm"),
                   "--no-progress"], env)
            timeline(env, scratch / "timeline")
            return 0
        def clockwork(k):
            return [sys.executable, "-m", "clockwork", "run", "ziemkiewicz_fig4a", "--out",
                    str(scratch / f"clockwork{k}"), "--no-progress"]

        def script(k):
            return [sys.executable, str(HERE / "fig4a_scipy.py"), "--out", str(scratch / f"scipy{k}")]

        rows = []
        for k in range(args.pairs + 1):
            a, b = timed(clockwork(k), env), timed(script(k), env)
            if k:
                rows.append((a, b, a / b))
                print(f"pair {k}: clockwork {a:.3f} s, script {b:.3f} s, ratio {a / b:.3f}", flush=True)
        med = [statistics.median(x) for x in zip(*rows)]
        print(f"median of {len(rows)} pairs: clockwork {med[0]:.3f} s, script {med[1]:.3f} s, "
              f"ratio {med[2]:.3f} (range {min(r[2] for r in rows):.3f} to {max(r[2] for r in rows):.3f})")
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
