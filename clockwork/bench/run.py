"""``clockwork bench``: accuracy against run time, beside other masters.

Every error is measured against a monolithic scipy solution of the same
equations (clockwork.reference: DOP853, rtol 1e-12, located discontinuities,
periodic-orbit shooting), and that reference is itself checked first
(``reference_checks``): against the AGM period of the free pendulum,
against Hoyng's stationary Eqs. (19)/(20), between its shooting and its
plain integration, between two tolerances, and against the co-simulation.

Problems and their errors:

- ``steady``: steady-state rate error E_T in s/day of the Ziemkiewicz
  Fig. 4(a) clock (Pendulum + GrasshopperEscapement, phi_r = 2 deg,
  Q = 1000, L = 1 m, m = 1 kg, g = 9.81) at 5 and 7 deg, and of the Fig. 2(b)
  chronometer (window (-2, 0) deg: the push before the lowest point, E_E < 0,
  see the seeds README), each torque refined on the reference so that the
  mean turning amplitude is exactly 5 or 7 deg;
- ``hoyng``: accumulated time error (s) at tick 1000 of Hoyng's torque-jump
  scene (L = g = 1, mu 2e-5 -> 4e-5 at t/2pi = 150, eps = 2.5e-4,
  phi0 = 0.03, start on the stationary swing of Eq. 19);
- ``chaos``: errors of long-time statistics of the two-oscillator clock of
  Ziemkiewicz Sec. VIII (mean rate in s/day, rms of a2 relative), since
  trajectories part after a few Lyapunov times;
- ``model_exchange``: the time of the 50th tick (s) of the free pendulum as
  a Model Exchange FMU (clockwork's wrapper with each solver, fmpy's CVode)
  and as the Co-Simulation Pendulum (bench/exchange.py).

Rows: master configurations (MasterSettings: Gauss-Seidel/Jacobi, input
extrapolation, event location, iterative coupling, Richardson; damping in
the Pendulum or in a Drag FMU) across communication steps and FMU
tolerances; a plain long run beside the steady-state shooting; peers on the
same FMUs through the SSP export (fmpy, libcosim, ecos; each in a
subprocess via clockwork/bench/peer_tool.py, so that a crash is a result) and
scipy itself.

Timing: medians of repeated runs, in this process for clockwork and scipy
(building and freeing the FMU instances included); for a peer, the wall time
of peer_tool.py inside its subprocess after the tool's modules are imported
(loading the FMUs, stepping and saving included; the interpreter's start-up
and the imports not).
"""

from __future__ import annotations

import dataclasses
import datetime
import json
import math
import os
import platform
import time
from pathlib import Path


from .config import BenchConfig, DAY, Row, fmt, full_config
from .checks import reference_checks
from .problems import steady_point
from .masters import build_time
from .peers import PeerRunner
from .exchange import bench_model_exchange
from .suites import bench_chaos, bench_hoyng, bench_steady
from .targets import summarize_targets, target_bench_master, target_fig4a, target_fig6
from .report import plot_work_precision, write_csv, write_markdown


def _machine() -> dict:
    load = os.getloadavg() if hasattr(os, "getloadavg") else (math.nan,) * 3
    return {"cpus": os.cpu_count(), "platform": platform.platform(), "python": platform.python_version(),
            "load": [round(x, 2) for x in load]}


def run_bench(out: Path, cfg: BenchConfig | None = None, progress: bool = True, command: str = "clockwork bench",
              checks_only: bool = False) -> dict:
    """Run the benchmark into `out`: bench.csv, bench.md, bench.json, work_precision.png."""
    cfg = cfg or full_config()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    work = out / "work"
    work.mkdir(exist_ok=True)
    t_start = time.perf_counter()
    load_start = _machine()["load"]

    def log(x):
        if not progress:
            return
        if isinstance(x, Row):
            x = (f"  {x.problem:<18} {x.family[:48]:<48} {x.label[:44]:<44} "
                 f"err {fmt(x.error):>9} {x.unit:<8} wall {fmt(x.wall_s):>8} s  "
                 f"{x.status if x.status != 'ok' else ''}")
        print(x, flush=True)

    info: dict = {}
    rows: list[Row] = []
    points = {}
    for key in cfg.steady_points:
        t0 = time.perf_counter()
        points[key] = steady_point(key)
        pt = points[key]
        info.setdefault("steady_points", {})[key] = {
            "torque_Nm": pt.params.torque, "amplitude_deg": math.degrees(pt.amplitude),
            "E_T_s_per_day": pt.E_T * DAY, "wall_s": time.perf_counter() - t0}
    log("reference checks ...")
    checks = reference_checks(points.get("fig4a_5deg"))
    for c in checks:
        log(f"  {'ok ' if c['ok'] else 'BAD'} {c['check']}: {c['value']:.3g} (bound {c['bound']:.3g} {c['unit']})")
    if not all(c["ok"] for c in checks):
        log("the reference does not pass its checks: errors below are measured against it anyway, see bench.md")
    targets: dict = {}
    if not checks_only:
        peers = PeerRunner(cfg, work)
        for key, pt in points.items():
            log(f"{key}: torque {pt.params.torque:.6g} N.m, E_T {pt.E_T * DAY:.6f} s/day")
            if "build_s" not in info:
                info["build_s"] = build_time(pt, cfg)
            rows += bench_steady(cfg, pt, peers, log)
        if cfg.hoyng:
            log("hoyng torque jump ...")
            r, info["hoyng"] = bench_hoyng(cfg, log)
            rows += r
        if cfg.chaos:
            log("chaotic clock ...")
            r, info["chaos"] = bench_chaos(cfg, peers, log)
            rows += r
        if cfg.model_exchange:
            log("the pendulum as a Model Exchange FMU ...")
            r, info["model_exchange"] = bench_model_exchange(cfg, log)
            rows += r
        if cfg.targets:
            log("targets: fig4a run, bench_master, Hoyng Fig. 6 ...")
            targets["fig4a"] = target_fig4a(cfg, work, log)
            targets["bench_master"] = target_bench_master(work)
            targets["fig6"] = target_fig6(cfg, work, log)
        targets["speed"] = summarize_targets(rows, targets)
    info["date"] = datetime.datetime.now().isoformat(timespec="seconds")
    info["wall_s"] = time.perf_counter() - t_start
    m = _machine()
    info["machine"] = {"cpus": m["cpus"], "platform": m["platform"], "python": m["python"],
                       "load_start": load_start, "load_end": m["load"]}
    write_csv(out / "bench.csv", rows)
    plot_work_precision(out / "work_precision.png", rows, info)
    write_markdown(out / "bench.md", cfg, rows, checks, info, targets, command)
    blob = {"config": cfg.name, "command": command, "info": info, "checks": checks,
            "rows": [dataclasses.asdict(r) for r in rows],
            "targets": json.loads(json.dumps(targets, default=lambda o: dataclasses.asdict(o)
                                             if dataclasses.is_dataclass(o) else repr(o)))}
    (out / "bench.json").write_text(json.dumps(blob, indent=1, default=repr) + "\n")
    return blob
