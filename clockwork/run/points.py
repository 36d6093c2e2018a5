"""One sweep point: its content address, and its run through the analysis.

``point_key`` hashes everything that determines a point's result (FMU
hashes, parameters, connections, master settings, experiment, analysis,
recorded outputs, input samples, the tool's version and code): the name under which the
point is stored in an output directory and in the cache.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import asdict

from ..version import __version__
from ..analyses import run_analysis
from ..analyses.context import experiment, master_settings, parameters
from ..errors import SimulationError
from ..hashing import source_digest


def analysis_kind(scene) -> str:
    return (scene.analysis or {}).get("kind", "time_series")


def point_key(scene, point: dict) -> str:
    """Content address of a sweep point's result."""
    blob = {
        "analysis_kind": analysis_kind(scene),  # stated on its own: two kinds never share an entry
        "fmus": {n: c.sha256 for n, c in sorted(scene.components.items())},
        "parameters": {n: dict(p) for n, p in parameters(scene, point).items()},
        "connections": [list(c) for c in scene.connections],
        # master.threads gives the bits of one thread: a result serves any count
        "master": {k: v for k, v in asdict(master_settings(scene, point)).items() if k != "threads"},
        "experiment": experiment(scene, point),
        "analysis": scene.analysis,
        "record": [list(scene.record.outputs), scene.record.interval, scene.record.ticks],
        "inputs": None if scene.inputs is None else [scene.inputs.sha256, scene.inputs.columns],
        "version": __version__,
        "code": source_digest(),
    }
    text = json.dumps(blob, sort_keys=True, default=repr)
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def point_label(point: dict) -> dict:
    """{"instance.variable": value} of a point, as written into results."""
    return {f"{a}.{b}": v for (a, b), v in point.items()}


def failed_point(scene, point: dict, e: SimulationError, wall_time_s: float | None = None) -> dict:
    """A point whose simulation failed: ``{"point", "error", "failed",
    "analysis_kind"}`` and, where the analysis kept it (``e.history``: a
    time series), what it recorded until the last good communication point
    (``series``, ``ticks``, ``statistics``). No "result": nothing reads it
    as a finished point (plots, the cache, a resumed sweep)."""
    failed = {"time_s": e.time, "last_point_s": getattr(e, "last_point", None), "instance": e.instance,
              "variable": e.variable, "message": e.message}
    history = dict(getattr(e, "history", None) or {})
    engine = history.pop("engine", None)
    if engine is not None:
        failed["engine"] = engine
    out = {"point": point_label(point), "error": str(e), "failed": failed, "analysis_kind": analysis_kind(scene),
           **history}
    if wall_time_s is not None:
        out["wall_time_s"] = wall_time_s
    return out


def run_point(scene, point: dict, progress: bool = False, catch: bool = False) -> dict:
    """One point: build, analyse, free. Returns a JSON-able dict (series as lists).

    With `catch`, a failed simulation is returned as a ``failed_point``
    instead of raised: one failed point of a sweep does not stop the others.
    """
    t0 = time.perf_counter()
    try:
        result = run_analysis(scene, point, progress=progress)
    except SimulationError as e:
        if not catch:
            raise
        return failed_point(scene, point, e, time.perf_counter() - t0)
    result["wall_time_s"] = time.perf_counter() - t0
    result["point"] = point_label(point)
    # What the point was computed for; its "kind" is the data's shape, which analyses share.
    result["analysis_kind"] = analysis_kind(scene)
    return result
