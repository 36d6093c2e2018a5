"""Analyses: what a scene measures at each sweep point.

Each analysis kind is a function ``f(scene, point, progress) -> dict`` with
keys ``kind``, ``result`` (JSON scalars), and optionally ``series``
(columns), ``ticks`` and ``statistics``. A module registers its kinds with
``@register(kind, keys)``, which also teaches the scene validator the
kind's allowed keys. Importing this package imports every analysis module.
"""

from __future__ import annotations

from typing import Callable

from ..scene import register_analysis

ANALYSES: dict[str, Callable] = {}


def register(kind: str, keys: set[str] | frozenset[str] = frozenset(), convert=None):
    def wrap(func):
        ANALYSES[kind] = func
        if convert is not None or kind not in ("steady_state", "time_series", "ticks"):
            register_analysis(kind, keys, convert)
        return func

    return wrap


def run_analysis(scene, point: dict, progress: bool = False) -> dict:
    kind = (scene.analysis or {}).get("kind", "time_series")
    if kind not in ANALYSES:
        raise KeyError(f"analysis kind {kind!r} has no implementation")
    return ANALYSES[kind](scene, point, progress=progress)


from . import basic, chaos, hoyng, ziemkiewicz  # noqa: E402,F401  (each registers its kinds)
