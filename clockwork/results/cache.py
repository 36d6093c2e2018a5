"""The point cache: finished sweep points, shared by output directories and runs.

Points are kept under the cache root (clockwork.paths.cache_root) as
``<code digest>/<key>.json``: ``key`` is clockwork.run.points.point_key
(FMU hashes, parameters, connections, master settings, experiment,
analysis, recorded outputs, version) and the code digest a hash of the
clockwork package's source, so that a changed analysis never reuses
results computed by older code. Points that failed are not cached.
"""

from __future__ import annotations

import json
from pathlib import Path

from ..hashing import source_digest
from ..paths import cache_root
from .files import write_json_atomic


def cache_dir() -> Path | None:
    """Where points are cached, or None when $CLOCKWORK_CACHE is off/0/empty."""
    root = cache_root()
    return None if root is None else root / source_digest()


def cache_load(key: str) -> dict | None:
    d = cache_dir()
    if d is None:
        return None
    f = d / f"{key}.json"
    try:
        return json.loads(f.read_text())
    except (OSError, json.JSONDecodeError):
        return None  # missing, unreadable or torn: compute


def cache_store(key: str, result: dict) -> None:
    d = cache_dir()
    if d is None or "error" in result:
        return
    try:
        d.mkdir(parents=True, exist_ok=True)
        write_json_atomic(d / f"{key}.json", result)
    except OSError:
        pass  # a read-only or full cache never fails a run
