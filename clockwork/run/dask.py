"""Sweeps on a Dask cluster.

``run_on_dask(address, scene, points, indices)`` ships the scene to the
workers as data, not as paths: the scene file's text, the ``--set``
overrides and every FMU's bytes go out once (``client.scatter``, broadcast);
a worker writes them into a folder named by their hash (in the cache, or
in the process's scratch folder when the cache is off), loads
the scene from there (model names resolve to the shipped FMUs through
CLOCKWORK_FMU_DIR, set only while the scene loads; paths ending .fmu are
rewritten to the shipped files) and runs its points exactly as the local
pool does (clockwork.run.points.run_point). It yields ``(index, result)`` as points
finish.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import threading
import tomllib
from pathlib import Path

from ..atomic import write_bytes_atomic, write_text_atomic
from ..errors import UsageError
from ..paths import cache_root, scratch_dir
from .catalog import load_scene
from .points import point_key, run_point


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
            "overrides": list(scene.overrides), "specs": specs, "fmus": fmus,
            "fmi_version": scene.master.fmi_version}


_ENV_LOCK = threading.Lock()
_SCENES: dict[str, object] = {}


def materialize(b: dict, root: Path | None = None):
    """Write a bundle into `root`/<key>/ (default: the temp dir) and load its scene."""
    if root is None:
        cache = cache_root()
        root = cache / "dask" if cache is not None else scratch_dir() / "dask"
    base = Path(root) / b["key"]
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
            # A model name resolves in the folder of the scene's build (paths.fmu_dir).
            sub = fmu_dir / "fmi3" if b.get("fmi_version", 2) == 3 else fmu_dir
            sub.mkdir(exist_ok=True)
            target = sub / f"{spec}.fmu"
        if not target.exists() or target.stat().st_size != len(data):
            write_bytes_atomic(target, data)
    scene_file = base / b["name"]
    if not scene_file.exists() or scene_file.read_text() != text:
        write_text_atomic(scene_file, text)
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
    scene = materialize(b)
    point = {tuple(k): v for k, v in point_items}
    return run_point(scene, point, catch=True)


def require_dask() -> None:
    """Refuse --scheduler in one line when the optional Dask extra is not installed."""
    import importlib.util

    if importlib.util.find_spec("distributed") is None:
        raise UsageError("--scheduler needs Dask, an optional extra: pip install 'clockwork-fmi[dask]'")


def run_on_dask(scheduler_address, scene, points: list[dict], indices: list[int]):
    """Run `points` (with their sweep `indices`) on a Dask cluster; yield (index, result) as they finish.

    `scheduler_address` is an address ("tcp://host:8786") or a
    distributed.Client.
    """
    require_dask()
    from distributed import Client, as_completed  # the optional extra, imported only when used

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
