"""The analyses registry: what a scene can measure, by kind.

An analysis kind is a function ``f(scene, point, progress) -> dict`` with
keys ``kind``, ``result`` (JSON scalars) and optionally ``series``
(columns), ``ticks`` and ``statistics``. A module registers it with
``@register(kind, keys, convert)``, which also tells the scene validator
the kind's allowed keys and their converter (``kinds``).
"""

from __future__ import annotations

from typing import Callable

from ..scene.kinds import Converter

ANALYSES: dict[str, Callable] = {}  # kind -> implementation
ANALYSIS_KEYS: dict[str, set[str]] = {}  # kind -> allowed keys besides `kind`
_ANALYSIS_CONVERT: dict[str, Converter] = {}  # kind -> converter of its table
# kind -> every column its `result` may hold (not all in every point): declared
# by the kinds that do, so that a plot of another name is refused at validation.
RESULT_COLUMNS: dict[str, frozenset[str]] = {}


def register_analysis(kind: str, keys: set[str] | frozenset[str] = frozenset(),
                      convert: Converter | None = None) -> None:
    """Allow ``[analysis] kind = "<kind>"`` with the given keys in scene files.

    `convert(table)` gets the analysis table without `kind` (only allowed
    keys, raw TOML values) and returns the converted values; it raises
    ``Invalid(key, expected)`` for a bad value.
    """
    ANALYSIS_KEYS[kind] = set(keys)
    if convert is not None:
        _ANALYSIS_CONVERT[kind] = convert
    else:
        _ANALYSIS_CONVERT.pop(kind, None)


def register(kind: str, keys: set[str] | frozenset[str] = frozenset(), convert: Converter | None = None,
             columns: set[str] | frozenset[str] | None = None):
    """Decorator: the function implements analysis `kind` (see register_analysis);
    `columns`, when given, every key its results' `result` table may hold."""
    def wrap(func):
        ANALYSES[kind] = func
        register_analysis(kind, keys, convert)
        if columns is not None:
            RESULT_COLUMNS[kind] = frozenset(columns)
        else:
            RESULT_COLUMNS.pop(kind, None)
        return func

    return wrap


def run_analysis(scene, point: dict, progress: bool = False) -> dict:
    kind = (scene.analysis or {}).get("kind", "time_series")
    if kind not in ANALYSES:
        raise KeyError(f"analysis kind {kind!r} has no implementation")
    return ANALYSES[kind](scene, point, progress=progress)
