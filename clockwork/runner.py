"""Run a scene: every sweep point through an analysis, then write the results.

Each finished sweep point is written to ``DIR/points/<key>.json`` as soon
as it completes, where the key hashes everything that determines the
result (FMU hashes, parameters, master settings, analysis). A rerun into
the same directory loads finished points instead of recomputing them, so an
interrupted sweep resumes without losing or repeating work.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict
from pathlib import Path

import numpy as np

from . import __version__
from .analyses import run_analysis
from .errors import SimulationError
from .master import MasterSettings
from .results import write_csv_atomic, write_json_atomic
from .system import System


def master_settings(scene, point: dict | None = None) -> MasterSettings:
    values = scene.master.as_dict()
    for (group, key), value in (point or {}).items():
        if group == "master":
            values[key] = value
    return MasterSettings(**values)


def experiment(scene, point: dict | None = None) -> tuple[float, float]:
    start, stop = scene.experiment.start, scene.experiment.stop
    for (group, key), value in (point or {}).items():
        if group == "experiment":
            start, stop = (value, stop) if key == "start" else (start, value)
    return start, stop


def parameters(scene, point: dict | None = None) -> dict[str, dict]:
    params = scene.parameters()
    for (inst, var), value in (point or {}).items():
        if inst in params:
            params[inst][var] = value
    return params


def build_system(scene, point: dict | None = None, record: dict[str, list[str]] | None = None) -> System:
    params = parameters(scene, point)
    start, _ = experiment(scene, point)
    components = {n: (str(c.fmu_path), params[n]) for n, c in scene.components.items()}
    mds = {n: c.model_description for n, c in scene.components.items()}
    return System(components, [tuple(c) for c in scene.connections], master_settings(scene, point),
                  record=record, start_time=start, model_descriptions=mds)


_CODE_DIGEST: str | None = None


def _code_digest() -> str:
    """Hash of the package's own sources: a changed master must not reuse
    results cached by an older one."""
    global _CODE_DIGEST
    if _CODE_DIGEST is None:
        h = hashlib.sha256()
        for f in sorted(Path(__file__).resolve().parent.rglob("*.py")):
            h.update(f.read_bytes())
        _CODE_DIGEST = h.hexdigest()[:16]
    return _CODE_DIGEST


def point_key(scene, point: dict) -> str:
    """Content address of a sweep point's result."""
    blob = {
        "fmus": {n: c.sha256 for n, c in sorted(scene.components.items())},
        "parameters": parameters(scene, point),
        "connections": [list(c) for c in scene.connections],
        "master": asdict(master_settings(scene, point)),
        "experiment": experiment(scene, point),
        "analysis": scene.analysis,
        "record": [list(scene.record.outputs), scene.record.interval, scene.record.ticks],
        "version": __version__,
        "code": _code_digest(),
    }
    text = json.dumps(blob, sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def _point_label(point: dict) -> dict:
    return {f"{a}.{b}": v for (a, b), v in point.items()}


def run_point(scene, point: dict, progress: bool = False) -> dict:
    """One point: build, analyse, free. Returns a JSON-able dict (series as lists)."""
    t0 = time.perf_counter()
    result = run_analysis(scene, point, progress=progress)
    result["wall_time_s"] = time.perf_counter() - t0
    result["point"] = _point_label(point)
    return result


_scene_cache: dict = {}


def _worker(scene_path: str, overrides: tuple, point_items: list) -> dict:
    from .scene import load_scene

    key = (scene_path, overrides)
    if key not in _scene_cache:
        _scene_cache[key] = load_scene(scene_path, overrides)
    point = {tuple(k): v for k, v in point_items}
    try:
        return run_point(_scene_cache[key], point)
    except SimulationError as e:
        return {"point": _point_label(point), "error": str(e)}


def run_scene(scene, out_dir, workers: int | None = None, scheduler: str | None = None,
              progress: bool = True) -> dict:
    out = Path(out_dir)
    t_start = time.perf_counter()
    points = scene.points()
    sweep = scene.sweep is not None
    results: list[dict | None] = [None] * len(points)
    keys = [point_key(scene, p) for p in points]
    store = out / "points"
    if sweep:
        store.mkdir(parents=True, exist_ok=True)
        for i, k in enumerate(keys):
            f = store / f"{k}.json"
            if f.exists():
                try:
                    results[i] = json.loads(f.read_text())
                except json.JSONDecodeError:
                    results[i] = None  # a torn file from a killed run: recompute
            # >>> content-addressed cache across output dirs (clockwork.sweep)
            if results[i] is None:
                from .sweep import cache_load

                results[i] = cache_load(k)
                if results[i] is not None:
                    write_json_atomic(f, results[i])
            # <<< cache
    todo = [i for i, r in enumerate(results) if r is None]
    reused = len(points) - len(todo)

    def finished(i: int, r: dict) -> None:
        results[i] = r
        if sweep:
            write_json_atomic(store / f"{keys[i]}.json", r)
            from .sweep import cache_store  # >>> cache <<<

            cache_store(keys[i], r)

    if not sweep:
        finished(0, run_point(scene, points[0], progress=progress))
    elif todo:
        from tqdm import tqdm

        bar = tqdm(total=len(points), initial=reused, disable=not progress, delay=1.0,
                   desc=scene.path.stem, unit="point")
        n_workers = workers or _default_workers(len(todo))
        if scheduler:
            from .sweep import run_on_dask

            for i, r in run_on_dask(scheduler, scene, [points[i] for i in todo], todo):
                finished(i, r)
                bar.update()
        elif n_workers <= 1:
            for i in todo:
                try:
                    r = run_point(scene, points[i])
                except SimulationError as e:
                    r = {"point": _point_label(points[i]), "error": str(e)}
                finished(i, r)
                bar.update()
        else:
            with ProcessPoolExecutor(n_workers) as pool:
                futures = {
                    pool.submit(_worker, str(scene.path), tuple(scene.overrides),
                                [[list(k), v] for k, v in points[i].items()]): i
                    for i in todo
                }
                for f in as_completed(futures):
                    finished(futures[f], f.result())
                    bar.update()
        bar.close()

    from .report import write_outputs

    summary = {
        "scene": str(scene.path),
        "title": scene.title,
        "reproduces": scene.reproduces,
        "tool": {"name": "clockwork", "version": __version__},
        "fmus": {n: {"file": str(c.fmu_path), "sha256": c.sha256, "model": c.model_description.modelName}
                 for n, c in scene.components.items()},
        "settings": {"master": scene.master.as_dict(), "experiment": asdict(scene.experiment),
                     "analysis": scene.analysis, "overrides": list(scene.overrides)},
        "points_total": len(points),
        "points_reused": reused,
    }
    write_outputs(scene, out, results, summary, t_start)
    return summary


def _default_workers(n_points: int) -> int:
    """Processes pay ~0.5 s of imports each: use them only for long sweeps."""
    cpus = os.cpu_count() or 1
    return 1 if n_points < 40 else min(cpus, max(1, n_points // 20))
