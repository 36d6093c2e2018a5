"""Rows of other co-simulation tools (fmpy, libcosim, ecos), each in its own process."""

from __future__ import annotations

import importlib.util
import json
import math
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ..paths import scratch_dir
from ..run.catalog import load_scene
from ..scene.ssp import export_ssp
from .config import BenchConfig, PEER_MODULES, ROOT, Row


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(float(v)) if isinstance(v, float) else str(v)
    return json.dumps(v)


def scene_toml(title: str, components: dict, links: list[str], step: float, stop: float) -> str:
    lines = ["connections = ["] + [f'  "{c}",' for c in links] + ["]", ""]
    lines += ["[scene]", f"title = {json.dumps(title)}", ""]
    for name, (fmu, params) in components.items():
        ps = ", ".join(f"{k} = {_toml_value(v)}" for k, v in params.items())
        lines += [f"[components.{name}]", f'fmu = "{fmu}"', f"parameters = {{ {ps} }}", ""]
    lines += ["[experiment]", "start = 0.0", f"stop = {stop!r}", "", "[master]", f"step = {step!r}", ""]
    return "\n".join(lines)


def export_scene(path: Path, text: str) -> Path:
    """Write a scene file and its SSP archive beside it; returns the archive."""
    path.write_text(text)
    ssp = path.with_suffix(".ssp")
    export_ssp(load_scene(path), ssp)
    return ssp


def tool_available(tool: str) -> str | None:
    """None when the tool's Python package can be found, else the reason."""
    module = PEER_MODULES.get(tool)
    if module is None:
        return f"unknown tool {tool!r}"
    try:
        found = importlib.util.find_spec(module) is not None
    except ModuleNotFoundError:
        found = False
    return None if found else f"not installed ({module} not importable)"


_TIMER = """
import importlib, runpy, sys, time
script, modules, time_file = sys.argv[1], sys.argv[2], sys.argv[3]
for m in filter(None, modules.split(",")):
    importlib.import_module(m)
sys.argv = [script] + sys.argv[4:]
t0 = time.perf_counter()
code = 0
try:
    runpy.run_path(script, run_name="__main__")
except SystemExit as e:
    code = e.code
if not code:
    open(time_file, "w").write(repr(time.perf_counter() - t0))
sys.exit(code)
"""


_PRELOAD = {
    "fmpy": "numpy,clockwork.scene.ssp,fmpy.ssp.simulation",
    "libcosim": "numpy,clockwork.scene.ssp,libcosimpy.CosimExecution,libcosimpy.CosimLogging,libcosimpy.CosimObserver",
    "ecos": "numpy,clockwork.scene.ssp,ecospy",
}


def run_peer(cfg: BenchConfig, tool: str, ssp: Path, steps: int, step: float, names: list[str],
             out: Path) -> tuple[dict | None, float, float, str]:
    """peer_tool.py in a subprocess: (arrays or None, script wall s, process wall s, status)."""
    if not Path(cfg.run_tool).exists():
        return None, math.nan, math.nan, f"not run: {cfg.run_tool} is missing"
    time_file = out.with_suffix(".time")
    time_file.unlink(missing_ok=True)
    cmd = [sys.executable, "-c", _TIMER, str(cfg.run_tool), _PRELOAD.get(tool, ""), str(time_file),
           tool, str(ssp), "--steps", str(steps), "--step", repr(step), "--out", str(out), *names]
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else []))
    # ecos unpacks each SSP into the temporary directory and leaves it: a folder of our own, removed after.
    scratch = tempfile.TemporaryDirectory(prefix="peer.", dir=scratch_dir())
    env["TMPDIR"] = scratch.name
    t0 = time.perf_counter()
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=cfg.peer_timeout_s, env=env)
    except subprocess.TimeoutExpired:
        return None, math.nan, time.perf_counter() - t0, f"timed out after {cfg.peer_timeout_s:g} s"
    finally:
        scratch.cleanup()
    process = time.perf_counter() - t0
    if p.returncode != 0:
        if p.returncode < 0:
            try:
                what = f"crashed ({signal.Signals(-p.returncode).name})"
            except ValueError:
                what = f"crashed (signal {-p.returncode})"
        else:
            what = f"exited with {p.returncode}"
        tail = " ".join((p.stderr or p.stdout).strip().splitlines()[-1:])[:200]
        return None, math.nan, process, f"{what}: {tail}" if tail else what
    try:
        wall = float(time_file.read_text())
        with np.load(out) as data:
            return {k: data[k] for k in data.files}, wall, process, "ok"
    except Exception as e:  # noqa: BLE001
        return None, math.nan, process, f"no readable result: {type(e).__name__}: {e}"


class PeerRunner:
    """Peers in subprocesses, repeated like clockwork's rows when short."""

    def __init__(self, cfg: BenchConfig, work: Path):
        self.cfg, self.work = cfg, work

    def run(self, row: Row, tool: str, ssp: Path, steps: int, step: float, names: list[str]):
        reason = tool_available(tool)
        if reason is not None:
            row.status = reason
            return None
        walls, processes = [], []
        while True:
            res, wall, process, status = run_peer(self.cfg, tool, ssp, steps, step, names,
                                                  self.work / f"{ssp.stem}.{tool}.npz")
            if res is None:
                row.status = status
                if math.isfinite(process):
                    row.note = f"after {process:.3g} s"
                return None
            walls.append(wall)
            processes.append(process)
            if len(walls) >= self.cfg.repeats or wall >= self.cfg.repeat_below_s:
                break
        row.wall_s, row.repeats = statistics.median(walls), len(walls)
        row.note = f"whole process {statistics.median(processes):.3g} s"
        return res


def tick_times(values: np.ndarray) -> np.ndarray:
    v = np.asarray(values, dtype=float)
    v = v[v > 0.0]
    if v.size == 0:
        return v
    return v[np.r_[True, np.diff(v) != 0.0]]
