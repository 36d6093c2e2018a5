"""Sweep points on this machine's cores: a pool of worker processes.

Each worker loads the scene once (from its file and ``--set`` overrides)
and runs the points it is given; results come back as points finish.
"""

from __future__ import annotations

import atexit
import os
import signal
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

from .. import watchdog
from ..analyses.context import reusing_systems
from ..errors import SimulationError
from ..paths import scratch_dir, scratch_inside
from ..processes import die_with_parent
from .catalog import load_scene
from .points import run_point

_scenes: dict = {}  # per worker process: (path, overrides) -> Scene


def _start_worker(parent: int, scratch: str) -> None:
    """A worker must not outlive its parent: when the parent dies (even by
    SIGKILL) the kernel sends the worker SIGKILL too (Linux prctl). Its
    scratch folder lies in the parent's, and SIGTERM and SIGHUP end it at
    once (it may be ended at any moment: nothing of it needs cleaning up).
    Its points share their FMU instances for the worker's whole life. A
    signal the run ignores (SIGHUP under nohup) the worker ignores too: a
    hang-up sent to the whole process group must not end the workers of a
    run that outlives it."""
    die_with_parent(parent)
    scratch_inside(Path(scratch))
    from ..fmi.calls import quiet_crashes

    quiet_crashes()  # a crash that ends this process is reported by the parent, in its one line
    for sig in (signal.SIGTERM, signal.SIGHUP):
        if signal.getsignal(sig) is not signal.SIG_IGN:
            signal.signal(sig, signal.SIG_DFL)
    reuse = reusing_systems()
    reuse.__enter__()
    atexit.register(reuse.__exit__, None, None, None)


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
    pool = ProcessPoolExecutor(workers, initializer=_start_worker, initargs=(os.getpid(), str(scratch_dir())))
    # Killed at once when the watchdog ends a run whose main thread is stuck
    # (before the scratch folder they write into is removed).
    token = watchdog.on_abandon(lambda: _kill_workers(pool), process=True)
    try:
        futures = {
            pool.submit(_worker, str(scene.path), tuple(scene.overrides),
                        [[list(k), v] for k, v in p.items()]): i
            for i, p in zip(indices, points)
        }
        # The workers, held here: a broken pool's manager thread may drop its
        # own list before the line below asks how they ended (forked workers
        # all start at the first submit).
        workers = list((getattr(pool, "_processes", None) or {}).values())
        for f in as_completed(futures):
            try:
                result = f.result()
            except BrokenProcessPool:
                raise SimulationError(
                    f"a sweep worker process ended abruptly{_how_workers_ended(workers)} while the point of sweep "
                    f"index {futures[f]} ran: the sweep stops; its finished points are kept in points/ for a "
                    f"rerun") from None
            yield futures[f], result
    except BaseException:
        # Interrupted (or the consumer stopped): the points still running are
        # not waited for; the finished ones are already stored for a rerun.
        _stop_now(pool)
        raise
    finally:
        watchdog.forget(token)
    pool.shutdown(wait=True)


def _how_workers_ended(workers: list) -> str:
    """The exit of the dead ones of `workers` (multiprocessing processes), as " (killed by SIGKILL)",
    " (exit code 1)", or "" when none has ended."""
    # A killed worker's pipe closes (which breaks the pool) a moment before
    # its exit status can be read: wait a little for one to show.
    # The broken pool terminates the others (SIGTERM), and one of those can
    # show before the cause does: wait for an end that is not the pool's own.
    deadline = time.monotonic() + 1.0
    ends = _exits(workers)
    while not ends - {"killed by SIGTERM"} and workers and time.monotonic() < deadline:
        time.sleep(0.01)
        ends = _exits(workers)
    ends = ends - {"killed by SIGTERM"} or ends
    return f" ({', '.join(sorted(ends))})" if ends else ""


def _exits(workers: list) -> set[str]:
    ends = set()
    for w in workers:
        code = w.exitcode
        if code is None:
            continue
        if code < 0:
            try:
                ends.add(f"killed by {signal.Signals(-code).name}")
            except ValueError:
                ends.add(f"killed by signal {-code}")
        elif code:
            ends.add(f"exit code {code}")
    return ends


def _kill_workers(pool: ProcessPoolExecutor) -> None:
    for w in list((getattr(pool, "_processes", None) or {}).values()):
        try:
            w.kill()
            w.join(timeout=2)
        except (OSError, ValueError, AssertionError):
            pass


def _stop_now(pool: ProcessPoolExecutor) -> None:
    """Cancel what has not started, kill the workers and reap them."""
    workers = list((getattr(pool, "_processes", None) or {}).values())  # no public handle before 3.14
    pool.shutdown(wait=False, cancel_futures=True)
    for w in workers:
        try:
            w.kill()
        except (OSError, ValueError):
            pass
    for w in workers:
        w.join(timeout=10)
