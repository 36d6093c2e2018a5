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
# kind -> every column its `result` may hold (not all in every point): a set,
# or a function of the scene for names that carry an instance's name or a
# configured value. A plot of another name is refused at validation.
RESULT_COLUMNS: dict[str, frozenset[str] | Callable] = {}
# kind -> every column its `series` may hold (empty: it has none), the same way.
SERIES_COLUMNS: dict[str, frozenset[str] | Callable] = {}


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
             columns: set[str] | frozenset[str] | Callable | None = None,
             series: set[str] | frozenset[str] | Callable | None = None):
    """Decorator: the function implements analysis `kind` (see register_analysis);
    `columns`, every key its results' `result` table may hold, and `series`,
    every column of its `series` (empty: none): a set, or ``f(scene) -> set``
    when names depend on the scene. Every kind of clockwork's own declares
    them; without, a plot's columns are checked only once the points are
    computed."""
    def wrap(func):
        ANALYSES[kind] = func
        register_analysis(kind, keys, convert)
        for table, declared in ((RESULT_COLUMNS, columns), (SERIES_COLUMNS, series)):
            if declared is None:
                table.pop(kind, None)
            else:
                table[kind] = declared if callable(declared) else frozenset(declared)
        return func

    return wrap


def _declared(table: dict, scene) -> frozenset[str] | None:
    columns = table.get((scene.analysis or {}).get("kind", "time_series"))
    if columns is None:
        return None
    return frozenset(columns(scene) if callable(columns) else columns)


def result_columns(scene) -> frozenset[str] | None:
    """Every column the `result` of the scene's analysis may hold, or None
    when its kind does not declare them."""
    return _declared(RESULT_COLUMNS, scene)


def series_columns(scene) -> frozenset[str] | None:
    """Every column the `series` of the scene's analysis may hold (empty:
    it has none), or None when its kind does not declare them."""
    return _declared(SERIES_COLUMNS, scene)


def run_analysis(scene, point: dict, progress: bool = False) -> dict:
    kind = (scene.analysis or {}).get("kind", "time_series")
    if kind not in ANALYSES:
        raise KeyError(f"analysis kind {kind!r} has no implementation")
    return ANALYSES[kind](scene, point, progress=progress)
