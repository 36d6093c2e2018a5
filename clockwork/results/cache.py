"""Finished sweep points: read back only when they are what they claim to be.

A point's result is stored twice: in the run's ``points/<key>.json`` (for
resuming) and in the cache shared by output directories and runs, under
the cache root (clockwork.paths.cache_root) as ``<code digest>/<key>.json``.
``key`` is clockwork.run.points.point_key (FMU hashes, parameters,
connections, master settings, experiment, analysis, recorded outputs,
version) and the code digest a hash of the clockwork package's source, so
that a changed analysis never reuses results computed by older code.

What is read back is checked (``check_point``): strict JSON, the shape of a
result, finite numbers, the same point and analysis kind (``analysis_kind``, the
[analysis] kind it was computed for). A file that fails
is computed again, with one warning line. Points that failed are neither
cached nor reused: a rerun tries them again.
"""

from __future__ import annotations

import math
from pathlib import Path

from ..errors import say
from ..hashing import source_digest
from ..files import read_regular
from ..numbers import parse_json
from ..paths import cache_root
from ..atomic import remove_stale_parts
from .files import write_json_atomic

_SCALARS = (str, int, float, bool, type(None))


# Cache folders made (or found unusable, and reported once) in this process:
# one mkdir per process, not one per point.
_ready: set[Path] = set()
_unusable: set[Path] = set()


def cache_dir() -> Path | None:
    """Where points are cached, or None when $CLOCKWORK_CACHE is off/0/empty
    or the folder cannot be made (said once, then the run goes on without it)."""
    root = cache_root()
    if root is None:
        return None
    d = root / source_digest()
    if d in _ready:
        return d
    if d in _unusable:
        return None
    try:
        d.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        _give_up(d, e)
        return None
    _ready.add(d)
    return d


def _give_up(d: Path, e: OSError) -> None:
    _ready.discard(d)
    _unusable.add(d)
    say("warning", f"the point cache {d} cannot be used ({e.strerror or e}): running without it "
                   "(set CLOCKWORK_CACHE to a writable folder, or to off)")


def check_point(data, label: dict, kind: str) -> str | None:
    """Why `data` is not a finished result of the point `label` of analysis
    `kind`, or None when it is one."""
    if not isinstance(data, dict):
        return "not a JSON object"
    if "error" in data:
        return "a failed point (tried again)"
    if data.get("point") != label:
        return "it belongs to another point"
    if data.get("analysis_kind") != kind:
        return f"it holds a result of analysis {data.get('analysis_kind')!r}, not {kind!r}"
    result = data.get("result")
    if not isinstance(result, dict) or not all(isinstance(v, _SCALARS) for v in result.values()):
        return "no result table of numbers and text"
    series = data.get("series", {})
    if not isinstance(series, dict) or not all(isinstance(c, list) for c in series.values()):
        return "series that are not columns"
    if len({len(c) for c in series.values()}) > 1 and kind in ("time_series", "ticks"):
        return "series columns of different lengths"
    bad = _first_bad_number(data)
    if bad is not None:
        return f"a value that is not a finite number at {bad}"
    return None


def _first_bad_number(x, where: str = "") -> str | None:
    if isinstance(x, bool) or x is None or isinstance(x, str):
        return None
    if isinstance(x, (int, float)):
        return None if math.isfinite(x) else where or "/"
    if isinstance(x, dict):
        for k, v in x.items():
            if not isinstance(k, str):
                return where or "/"
            found = _first_bad_number(v, f"{where}/{k}")
            if found:
                return found
        return None
    if isinstance(x, list):
        for i, v in enumerate(x):
            found = _first_bad_number(v, f"{where}[{i}]")
            if found:
                return found
        return None
    return where or "/"


def read_point(path: Path, label: dict, kind: str) -> dict | None:
    """A stored point's result, or None (missing; or damaged, with one warning line)."""
    try:
        text = read_regular(path, "a JSON file").decode()
    except FileNotFoundError:
        return None
    except OSError as e:
        _warn(path, f"cannot read it ({e.strerror})")
        return None
    try:
        data = parse_json(text)
    except ValueError as e:
        _warn(path, f"not strict JSON ({' '.join(str(e).split())})")
        return None
    problem = check_point(data, label, kind)
    if problem is not None:
        if "error" not in data:  # a failed point is retried without a warning: it was reported
            _warn(path, problem)
        return None
    return data


def _warn(path: Path, why: str) -> None:
    say("warning", f"{path}: {why}; computing the point again")


def cache_load(key: str, label: dict, kind: str) -> dict | None:
    d = cache_dir()
    return None if d is None else read_point(d / f"{key}.json", label, kind)


def cache_store(key: str, result: dict) -> None:
    d = cache_dir()
    if d is None or "error" in result:
        return
    try:
        remove_stale_parts(d)
        write_json_atomic(d / f"{key}.json", result)
    except OSError as e:
        _give_up(d, e)  # a read-only or full cache never fails a run
