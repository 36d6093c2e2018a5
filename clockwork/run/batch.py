"""A list of points of one scene, run as a sweep runs them, for a caller
that needs their results back rather than written: the fit
(clockwork.run.fit), which asks for the same rows at new parameter values
at every step of its optimizer.

Each point is looked up in the point cache first (clockwork.results.cache,
under its content address, clockwork.run.points.point_key), then run where
a sweep would run it: in this process (reusing the FMU instances of the
last point inside the caller's ``analyses.context.reusing_systems()``), in
the local process pool (clockwork.run.pool) or on a Dask cluster
(clockwork.run.dask). Finished points go into the cache; failed ones are
returned as ``points.failed_point`` dicts (with "error"), never cached.

A cached result found under a point's key but written for another label
(the key hashes the effective parameters: a fit's row that sets
escapement.torque to the scene's own value is the point of a sweep that
leaves it alone) is the same computation: it is taken, under this point's
label, without the warning a damaged file gets.
"""

from __future__ import annotations

from ..files import read_regular
from ..numbers import parse_json
from ..results.cache import cache_dir, cache_load, cache_store, check_point
from .points import analysis_kind, point_key, point_label, run_point


def run_points(scene, points: list[dict], workers: int | None = None, scheduler: str | None = None,
               cache: bool = True) -> list[dict]:
    """The results of `points` ({(instance, variable): value} each), in their order."""
    kind = analysis_kind(scene)
    keys = [point_key(scene, p) for p in points]
    results: list[dict | None] = [_cached(k, point_label(p), kind) if cache else None
                                  for k, p in zip(keys, points)]
    todo = [i for i, r in enumerate(results) if r is None]
    if todo:
        if scheduler:
            from .dask import run_on_dask  # distributed is an optional extra

            done = run_on_dask(scheduler, scene, [points[i] for i in todo], todo)
        else:
            from .pool import default_workers, run_in_pool

            n_workers = workers or default_workers(len(todo))
            if n_workers <= 1:
                done = ((i, run_point(scene, points[i], catch=True)) for i in todo)
            else:
                done = run_in_pool(scene, [points[i] for i in todo], todo, n_workers)
        try:
            for i, r in done:
                results[i] = r
                if cache:
                    cache_store(keys[i], r)
        finally:
            if hasattr(done, "close"):
                done.close()  # a pool stops its workers now
    return results


def _cached(key: str, label: dict, kind: str) -> dict | None:
    """The cache's result for `key`, labelled `label` (see the module's docstring), or None."""
    d = cache_dir()
    if d is None:
        return None
    try:
        data = parse_json(read_regular(d / f"{key}.json", "a JSON file"))
    except (OSError, ValueError):
        data = None
    if isinstance(data, dict) and isinstance(data.get("point"), dict) and data["point"] != label \
            and check_point(data, data["point"], kind) is None:
        return {**data, "point": label}
    return cache_load(key, label, kind)  # the usual reading: a damaged file is said so and run again
