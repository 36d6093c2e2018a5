"""The analyses registry: what a scene can measure, by kind.

An analysis kind is a function ``f(scene, point, progress) -> dict`` with
keys ``kind``, ``result`` (JSON scalars) and optionally ``series``
(columns), ``ticks`` and ``statistics``. A module registers it with
``@register(kind, keys, convert)``, which also tells the scene validator
the kind's allowed keys and their converter (``kinds``).
"""

from __future__ import annotations

from typing import Callable

from ..errors import SceneError
from ..scene.kinds import Converter, Invalid
from ..scene.model import show

ANALYSES: dict[str, Callable] = {}  # kind -> implementation
ANALYSIS_KEYS: dict[str, set[str]] = {}  # kind -> allowed keys besides `kind`
_ANALYSIS_CONVERT: dict[str, Converter] = {}  # kind -> converter of its table
# kind -> every column its `result` may hold (not all in every point): a set,
# or a function of the scene for names that carry an instance's name or a
# configured value. A plot of another name is refused at validation.
RESULT_COLUMNS: dict[str, frozenset[str] | Callable] = {}
# kind -> every column its `series` may hold (empty: it has none), the same way.
SERIES_COLUMNS: dict[str, frozenset[str] | Callable] = {}
# kind -> check(scene, point) of its keys against the scene at one sweep point
# (the FMUs' ranges, the span, the step); raises Invalid(key, expected).
CHECKS: dict[str, Callable] = {}


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
             series: set[str] | frozenset[str] | Callable | None = None,
             check: Callable | None = None):
    """Decorator: the function implements analysis `kind` (see register_analysis);
    `columns`, every key its results' `result` table may hold, and `series`,
    every column of its `series` (empty: none): a set, or ``f(scene) -> set``
    when names depend on the scene. Every kind of clockwork's own declares
    them; without, a plot's columns are checked only once the points are
    computed. `check(scene, point)` holds the kind's keys to what the scene
    at a sweep point accepts (raising ``Invalid(key, expected)``): what
    validate passes, the run does not refuse."""
    def wrap(func):
        ANALYSES[kind] = func
        register_analysis(kind, keys, convert)
        if check is None:
            CHECKS.pop(kind, None)
        else:
            CHECKS[kind] = check
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


def key_specs(kind: str) -> dict:
    """{key: keys.Key} of the kind's keys, from its converter's spec (a
    converter shared by several kinds holds the keys of all of them)."""
    spec = getattr(_ANALYSIS_CONVERT.get(kind), "spec", {})
    return {k: v for k, v in spec.items() if k in ANALYSIS_KEYS.get(kind, ())}


def key_table() -> list[str]:
    """The rows of docs/scenes.md's table of analysis keys: each key with the
    kinds that take it and what it accepts (a key whose bound differs
    between kinds gets a row per bound)."""
    rows: dict[tuple[str, str], list[str]] = {}
    for kind in sorted(ANALYSIS_KEYS):
        for key, spec in key_specs(kind).items():
            rows.setdefault((key, getattr(spec, "stated", "?")), []).append(kind)
    return [f"| `{key}` | {', '.join(f'`{k}`' for k in kinds)} | {stated} |"
            for (key, stated), kinds in sorted(rows.items())]


def check_analysis(scene) -> None:
    """The kind's check at every sweep point: one SceneError naming the file,
    the key (as the scene or a --set gave it) and what was expected."""
    kind = (scene.analysis or {}).get("kind", "time_series")
    check = CHECKS.get(kind)
    if check is None:
        return
    points = scene.points()
    for point in points:
        try:
            check(scene, point)
        except Invalid as e:
            raise SceneError(f"expected {e.expected}{_at(point, len(points))}", scene.path,
                             _label(scene, kind, e.key)) from None


def _label(scene, kind: str, key: str) -> str:
    """The key as the user gave it: `--set analysis.x` for an override,
    with its value where the value is a plain number (not converted from a
    unit), `(its default)` where the table leaves it out."""
    label = f"analysis.{key}"
    if any(o.split("=", 1)[0].strip() == label for o in scene.overrides):
        label = f"--set {label}"
    table = scene.analysis or {}
    if key not in table:
        return f"{label} (its default)"
    spec = key_specs(kind).get(key)
    plain = spec is not None and spec.bound.startswith(("a number", "an integer"))
    return f"{label} = {show(table[key])}" if plain else label


def _at(point: dict, n_points: int) -> str:
    if n_points < 2 or not point:
        return ""
    return " (at the sweep point " + ", ".join(f"{a}.{b} = {show(v)}" for (a, b), v in point.items()) + ")"


def run_analysis(scene, point: dict, progress: bool = False) -> dict:
    kind = (scene.analysis or {}).get("kind", "time_series")
    if kind not in ANALYSES:
        raise KeyError(f"analysis kind {kind!r} has no implementation")
    return ANALYSES[kind](scene, point, progress=progress)
