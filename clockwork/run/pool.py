"""Sweep points on this machine's cores: a pool of worker processes.

Each worker loads the scene once (from its file and ``--set`` overrides)
and runs the points it is given; results come back as points finish.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
from concurrent.futures import ProcessPoolExecutor, as_completed

from .catalog import load_scene
from .points import run_point

_scenes: dict = {}  # per worker process: (path, overrides) -> Scene


def _die_with_parent(parent: int) -> None:
    """A worker must not outlive its parent: when the parent dies (even by
    SIGKILL) the kernel sends the worker SIGKILL too (Linux prctl)."""
    if sys.platform.startswith("linux"):
        libc = ctypes.CDLL(None, use_errno=True)
        pr_set_pdeathsig = 1
        libc.prctl(pr_set_pdeathsig, signal.SIGKILL)
    if os.getppid() != parent:  # the parent died before prctl took effect
        os._exit(1)


def _worker(scene_path: str, overrides: tuple, point_items: list) -> dict:
    key = (scene_path, overrides)
    if key not in _scenes:
        _scenes[key] = load_scene(scene_path, overrides)
    point = {tuple(k): v for k, v in point_items}
    return run_point(_scenes[key], point, catch=True)


def default_workers(n_points: int) -> int:
    """Processes pay ~0.5 s of imports each: use them only for long sweeps."""
    cpus = os.cpu_count() or 1
    return 1 if n_points < 40 else min(cpus, max(1, n_points // 20))


def run_in_pool(scene, points: list[dict], indices: list[int], workers: int):
    """Run `points` (their sweep `indices`) in `workers` processes; yield (index, result)."""
    with ProcessPoolExecutor(workers, initializer=_die_with_parent, initargs=(os.getpid(),)) as pool:
        futures = {
            pool.submit(_worker, str(scene.path), tuple(scene.overrides),
                        [[list(k), v] for k, v in p.items()]): i
            for i, p in zip(indices, points)
        }
        for f in as_completed(futures):
            yield futures[f], f.result()
