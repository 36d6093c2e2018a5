"""The targets of a full run: whole-process timings and the verdicts of docs/benchmarks.md."""

from __future__ import annotations

import math
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path


from ..numbers import parse_json
from ..physics import reference
from .config import BenchConfig, DAY, DEFAULT_FAMILY, DEG, PEER_MODULES, ROOT, Row, TARGET_S_PER_DAY, TWO_PI


def _subprocess_wall(cmd: list[str], env: dict, timeout: float) -> tuple[float, subprocess.CompletedProcess]:
    t0 = time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=timeout, cwd=ROOT)
    return time.perf_counter() - t0, p


def target_fig4a(cfg: BenchConfig, work: Path, log) -> dict:
    """`clockwork run scenarios/ziemkiewicz_fig4a.toml` as a whole process,
    its wall time per point, and each point's E_T against the reference."""
    env = dict(os.environ, CLOCKWORK_CACHE="off")
    walls = []
    out = work / "fig4a_run"
    for k in range(max(1, cfg.repeats)):
        if out.exists():
            shutil.rmtree(out)
        wall, p = _subprocess_wall([sys.executable, "-m", "clockwork", "run", "scenarios/ziemkiewicz_fig4a.toml",
                                    "--out", str(out), "--no-progress"], env, 1800)
        if p.returncode != 0:
            return {"status": f"clockwork run failed: {p.stderr.strip()[-300:]}"}
        walls.append(wall)
        log(f"fig4a run {k + 1}: {wall:.2f} s")
    summary = parse_json((out / "summary.json").read_bytes())
    points = summary["points"]
    errors = []
    for pnt in points:
        r = pnt.get("result", pnt)
        torque = r.get("torque_Nm")
        if torque is None or r.get("stalled"):
            continue
        ss = reference.steady_state(reference.ClockParams(torque=torque, phi_r=2 * DEG, Q=1000.0))
        if ss.stalled:
            continue
        errors.append(abs(r["E_T_s_per_day"] - ss.E_T * DAY))
    n = summary.get("points_total", len(points))
    med = statistics.median(walls)
    return {"status": "ok", "process_wall_s": walls, "median_wall_s": med, "points": n,
            "wall_per_point_s": med / n, "in_run_wall_s": summary.get("wall_time_s"),
            "max_error_s_per_day": max(errors) if errors else math.nan, "points_compared": len(errors)}


def target_bench_master(work: Path) -> dict:
    script = ROOT / "benchmarks" / "bench_master.py"
    if not script.exists():
        return {"status": "benchmarks/bench_master.py missing"}
    wall, p = _subprocess_wall([sys.executable, str(script), "--steps", "20000", "--repeats", "5"],
                               dict(os.environ), 1800)
    if p.returncode != 0:
        return {"status": f"failed: {p.stderr.strip()[-300:]}"}
    return {"status": "ok", "table": p.stdout.strip(), "wall_s": wall}


def target_fig6(cfg: BenchConfig, work: Path, log) -> dict:
    """Hoyng Fig. 6 (4.8e6 periods, noisy torque) estimated from two shorter
    runs with the noise on from the start: wall = a + b periods."""
    env = dict(os.environ, CLOCKWORK_CACHE="off")
    pts = []
    for n in cfg.fig6_periods:
        out = work / f"fig6_{n}"
        if out.exists():
            shutil.rmtree(out)
        wall, p = _subprocess_wall([sys.executable, "-m", "clockwork", "run", "scenarios/hoyng_fig6.toml", "--out",
                                    str(out), "--no-progress", "--set", f"experiment.stop={n * TWO_PI!r}",
                                    "--set", "escapement.noise_start=0"], env, 3600)
        if p.returncode != 0:
            return {"status": f"clockwork run failed: {p.stderr.strip()[-300:]}"}
        pts.append((n, wall))
        log(f"fig6 {n} periods: {wall:.2f} s")
    (n1, w1), (n2, w2) = pts[0], pts[-1]
    b = (w2 - w1) / (n2 - n1)
    a = w1 - b * n1
    full = 4.8e6
    return {"status": "ok", "runs": pts, "per_period_ms": b * 1e3, "startup_s": a, "estimate_s": a + b * full,
            "periods": full}


def summarize_targets(rows: list[Row], targets: dict) -> list[dict]:
    """Per steady point: the fastest clockwork row within 1e-3 s/day beside each peer's best."""
    out = []
    for prob in ("fig4a_5deg", "fig4a_7deg", "fig2b_chronometer"):
        if not any(r.problem == prob for r in rows):
            continue
        mine = [r for r in rows if r.problem == prob and r.family == DEFAULT_FAMILY and r.status == "ok"
                and r.error <= TARGET_S_PER_DAY]
        best = min(mine, key=lambda r: r.wall_s) if mine else None
        entry = {"problem": prob, "clockwork": best, "peers": {}}
        peers = {"clockwork: plain long run": [r for r in rows if r.problem == prob
                                               and r.family.startswith("plain long run")]}
        peers.update({t: [r for r in rows if r.problem == prob and r.tool == t] for t in ("fmpy", "libcosim", "ecos")})
        for r in rows:
            if r.problem == prob and r.tool == "scipy":
                peers.setdefault(r.family, []).append(r)
        for tool, candidates in peers.items():
            peer_rows = [r for r in candidates if r.status == "ok" and math.isfinite(r.error)]
            if not peer_rows:
                status = candidates[0].status if candidates else "not run"
                entry["peers"][tool] = {"status": status}
                continue
            reach = [r for r in peer_rows if r.error <= TARGET_S_PER_DAY]
            if reach:
                fastest = min(reach, key=lambda r: r.wall_s)
                entry["peers"][tool] = {"reaches": True, "row": fastest,
                                        "ratio": fastest.wall_s / best.wall_s if best else math.nan}
            else:
                bestp = min(peer_rows, key=lambda r: r.error)
                est = _extrapolate(peer_rows) if tool in PEER_MODULES else None
                entry["peers"][tool] = {"reaches": False, "row": bestp, "estimate": est}
        out.append(entry)
    return out


def _extrapolate(peer_rows: list[Row]) -> dict | None:
    """Error ~ C h^p from the two finest fixed steps: the step and the wall
    time (~1/h) that 1e-3 s/day would take."""
    rs = sorted((r for r in peer_rows if r.step_s), key=lambda r: r.step_s)
    if len(rs) < 2 or rs[0].error <= 0 or rs[1].error <= 0 or rs[0].step_s == rs[1].step_s:
        return None
    a, b = rs[0], rs[1]
    p = math.log(b.error / a.error) / math.log(b.step_s / a.step_s)
    if not p > 0.1:
        return {"order": p}
    h = a.step_s * (TARGET_S_PER_DAY / a.error) ** (1.0 / p)
    return {"order": p, "step_s": h, "wall_s": a.wall_s * a.step_s / h}
