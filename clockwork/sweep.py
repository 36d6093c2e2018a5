"""Sweeps at scale: a Dask cluster, and a result cache shared by output dirs.

``run_on_dask(address, scene, points, indices)`` ships the scene to the
workers as data, not as paths: the scene file's text, the ``--set``
overrides and every FMU's bytes go out once (``client.scatter``, broadcast);
a worker writes them into a temporary directory named by their hash, loads
the scene from there (model names resolve to the shipped FMUs through
CLOCKWORK_FMU_DIR, set only while the scene loads; paths ending .fmu are
rewritten to the shipped files) and runs its points exactly as the local
pool does (runner.run_point). It yields ``(index, result)`` as points
finish.

The cache keeps finished points under ``$CLOCKWORK_CACHE`` (default
``~/.cache/clockwork``; ``off`` disables it) as ``<code>/<key>.json``:
``key`` is runner.point_key (FMU hashes, parameters, connections, master
settings, experiment, analysis, recorded outputs, version) and ``code`` a
hash of the clockwork package's source, so that a changed analysis never
reuses results computed by older code. Points that failed are not cached.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import tempfile
import threading
import tomllib
from pathlib import Path

from .results import write_json_atomic

# --- cache -----------------------------------------------------------------

_CODE_HASH: str | None = None


def code_hash() -> str:
    """sha256 (16 hex) of every clockwork/**/*.py file, names and contents."""
    global _CODE_HASH
    if _CODE_HASH is None:
        root = Path(__file__).resolve().parent
        h = hashlib.sha256()
        for f in sorted(root.rglob("*.py")):
            h.update(str(f.relative_to(root)).encode())
            h.update(b"\0")
            h.update(f.read_bytes())
        _CODE_HASH = h.hexdigest()[:16]
    return _CODE_HASH


def cache_dir() -> Path | None:
    """Where points are cached, or None when $CLOCKWORK_CACHE is off/0/empty."""
    env = os.environ.get("CLOCKWORK_CACHE")
    if env is not None and env.strip().lower() in ("", "0", "off", "no", "false"):
        return None
    base = Path(env).expanduser() if env else Path.home() / ".cache" / "clockwork"
    return base / code_hash()


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


# --- shipping a scene --------------------------------------------------------


def bundle(scene) -> dict:
    """Everything a worker needs, as data: scene text, overrides, FMU bytes."""
    text = Path(scene.path).read_text()
    specs = {}
    table = tomllib.loads(text).get("components", {})
    for name, comp in scene.components.items():
        specs[name] = table.get(name, {}).get("fmu", comp.model_name)
    fmus = {}
    for name, comp in scene.components.items():
        fmus[name] = Path(comp.fmu_path).read_bytes()
    h = hashlib.sha256(text.encode())
    for o in scene.overrides:
        h.update(o.encode())
    for name in sorted(fmus):
        h.update(name.encode())
        h.update(hashlib.sha256(fmus[name]).digest())
    return {"key": h.hexdigest()[:24], "name": Path(scene.path).name, "text": text,
            "overrides": list(scene.overrides), "specs": specs, "fmus": fmus}


_ENV_LOCK = threading.Lock()
_SCENES: dict[str, object] = {}


def materialize(b: dict, root: Path | None = None):
    """Write a bundle into `root`/<key>/ (default: the temp dir) and load its scene."""
    from .scene import load_scene

    base = Path(root or Path(tempfile.gettempdir()) / f"clockwork-dask-{os.getuid()}") / b["key"]
    hit = _SCENES.get(str(base))
    if hit is not None:
        return hit
    fmu_dir = base / "fmus"
    fmu_dir.mkdir(parents=True, exist_ok=True)
    text = b["text"]
    for name, spec in b["specs"].items():
        data = b["fmus"][name]
        if spec.endswith(".fmu"):
            target = fmu_dir / f"{name}__{Path(spec).name}"
            new = json.dumps(str(target))
            pattern = re.compile(r"""(["'])""" + re.escape(spec) + r"\1")
            text, n = pattern.subn(lambda _m: new, text)
            if n == 0:
                raise ValueError(f"cannot rewrite the FMU path {spec!r} of component {name}")
        else:
            target = fmu_dir / f"{spec}.fmu"
        if not target.exists() or target.stat().st_size != len(data):
            tmp = target.with_suffix(f".{threading.get_ident()}.part")
            tmp.write_bytes(data)
            os.replace(tmp, target)
    scene_file = base / b["name"]
    if not scene_file.exists() or scene_file.read_text() != text:
        tmp = scene_file.with_suffix(f".{threading.get_ident()}.part")
        tmp.write_text(text)
        os.replace(tmp, scene_file)
    # CLOCKWORK_FMU_DIR is process-wide: hold it only while the names resolve.
    with _ENV_LOCK:
        old = os.environ.get("CLOCKWORK_FMU_DIR")
        os.environ["CLOCKWORK_FMU_DIR"] = str(fmu_dir)
        try:
            scene = load_scene(scene_file, tuple(b["overrides"]))
        finally:
            if old is None:
                os.environ.pop("CLOCKWORK_FMU_DIR", None)
            else:
                os.environ["CLOCKWORK_FMU_DIR"] = old
    _SCENES[str(base)] = scene
    return scene


def _dask_point(b: dict, point_items: list) -> dict:
    """A worker's task: one sweep point of the shipped scene."""
    from .errors import SimulationError
    from .runner import _point_label, run_point

    scene = materialize(b)
    point = {tuple(k): v for k, v in point_items}
    try:
        return run_point(scene, point)
    except SimulationError as e:
        return {"point": _point_label(point), "error": str(e)}


def run_on_dask(scheduler_address, scene, points: list[dict], indices: list[int]):
    """Run `points` (with their sweep `indices`) on a Dask cluster; yield (index, result) as they finish.

    `scheduler_address` is an address ("tcp://host:8786") or a
    distributed.Client.
    """
    from distributed import Client, as_completed

    from .runner import point_key

    own = not isinstance(scheduler_address, Client)
    client = Client(scheduler_address) if own else scheduler_address
    try:
        shipped = client.scatter(bundle(scene), broadcast=True)
        futures = {}
        for i, p in zip(indices, points):
            f = client.submit(_dask_point, shipped, [[list(k), v] for k, v in p.items()],
                              key=f"clockwork-{point_key(scene, p)}-{i}", pure=False)
            futures[f] = i
        for f in as_completed(futures):
            yield futures[f], f.result()
    finally:
        if own:
            client.close()
