"""The plot-kind registry: PNG plots of a scene's results, in the papers' units.

A plot kind is ``f(scene, results, spec) -> Figure | None`` (None: nothing
to draw for these results). A module registers it with
``@register(kind, keys, convert)``, which also tells the scene validator
the kind's allowed keys (``title`` and ``file`` always) and their
converter. matplotlib is imported on the first plot, not at start-up, and
plots are drawn on ``matplotlib.figure.Figure`` without pyplot.
"""

from __future__ import annotations

import io
import logging
import sys
from pathlib import Path

import numpy as np

from ...atomic import write_bytes_atomic
from ...engine.names import split_ref
from ...paths import matplotlib_folder
from ...scene.kinds import Converter, Invalid

PLOTS: dict = {}  # kind -> function
PLOT_KEYS: dict[str, set[str]] = {}  # kind -> allowed keys besides `kind`
_PLOT_CONVERT: dict[str, Converter] = {}
# kind -> ({spec key naming columns: its default}, where the columns are: "series" or "rows")
PLOT_COLUMNS: dict[str, tuple[dict, str]] = {}


def matplotlib_config() -> None:
    """Give matplotlib a usable config folder before it is imported
    (paths.matplotlib_folder), and keep its log lines off stderr (one line
    per failure is ours to print)."""
    logging.getLogger("matplotlib").setLevel(logging.ERROR)
    matplotlib_folder()


def load_matplotlib() -> None:
    """Import what drawing a PNG needs (a third of a second: done once, on
    the first plot, or ahead of time by the plot process)."""
    if "matplotlib" not in sys.modules:
        matplotlib_config()
    import matplotlib.figure  # noqa: F401
    from matplotlib.backends import backend_agg  # noqa: F401


def subplots(*args, figsize: tuple[float, float], **kwargs):
    """A new figure and its axes, as ``pyplot.subplots`` takes them, without
    pyplot: no global list of figures to close, and no backend switched
    under the feet of a program that imports clockwork."""
    load_matplotlib()
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize)
    return fig, fig.subplots(*args, **kwargs)


def check_keys(t: dict, strings=("x", "title"), string_lists=(), booleans=()) -> dict:
    """The keys every plot kind shares (`title`, `file`, `levels`: contour
    levels, sorted), the given string keys, string-list keys (a string
    becomes a one-element list) and true/false keys."""
    out = dict(t)
    if "levels" in t:
        lv = t["levels"]
        if not (isinstance(lv, list) and lv and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                    for x in lv)):
            raise Invalid("levels", "a non-empty list of numbers")
        out["levels"] = sorted(float(x) for x in lv)
    for k in booleans:
        if k in t and not isinstance(t[k], bool):
            raise Invalid(k, "true or false")
    for k in strings:
        if k in t and not isinstance(t[k], str):
            raise Invalid(k, "a string")
    for k in string_lists:
        if k in t:
            v = t[k]
            if isinstance(v, str):
                out[k] = [v]
            elif isinstance(v, list) and v and all(isinstance(s, str) for s in v):
                out[k] = list(v)
            else:
                raise Invalid(k, "a string or a non-empty list of strings")
    if "file" in t:
        f = t["file"]
        # Only .png names: the result files (summary.json, *.csv) cannot be overwritten by a plot.
        if (not isinstance(f, str) or "/" in f or "\\" in f or f.startswith(".")
                or not f.lower().endswith(".png") or len(f) <= 4):
            raise Invalid("file", 'a .png file name without a directory, e.g. "fig.png"')
    return out


def single_run(results: list[dict], key: str = "series") -> dict | None:
    """The one result of a scene without a sweep, when it holds `key`; else None."""
    r = results[0] if results else None
    return r if r and key in r else None


def curves(rows: list[dict], key) -> dict:
    """Sweep rows grouped into curves by key(row), in the order they come."""
    out: dict = {}
    for r in rows:
        out.setdefault(key(r), []).append(r)
    return out


def register(kind: str, keys: set[str] | frozenset[str] = frozenset(), convert: Converter | None = None,
             run: str | None = None, rows=None, columns: dict | None = None):
    """Register ``f(scene, results, spec) -> Figure | None`` as plot kind `kind`.

    `columns` names the spec keys that name data columns, with their
    defaults (None: no default): a sweep axis or a result column, or (with
    `run`) a column of the run's series. They are checked against the
    results before anything is written (``unknown_column``), so that a
    typo is refused instead of drawn as an empty plot.

    With `run` (a key such as "series"), the kind plots the one result of a
    scene without a sweep: f gets that result instead of the list, and is
    not called when the result lacks `run`. With `rows` (a filter of the
    sweep's results), f gets the rows it keeps, and is not called when
    there are none.
    """
    def wrap(func):
        if run is not None:
            def plot_one(scene, results, spec):
                r = single_run(results, run)
                return None if r is None else func(scene, r, spec)
            PLOTS[kind] = plot_one
        elif rows is not None:
            def plot_rows(scene, results, spec):
                kept = rows(results)
                return func(scene, kept, spec) if kept else None
            PLOTS[kind] = plot_rows
        else:
            PLOTS[kind] = func
        PLOT_KEYS[kind] = set(keys) | {"title", "file"}
        PLOT_COLUMNS[kind] = (dict(columns or {}), run or "rows")
        if convert is not None:
            _PLOT_CONVERT[kind] = convert
        else:
            _PLOT_CONVERT.pop(kind, None)
        return func

    return wrap


def display(scene, name: str, values):
    """Values of `instance.variable` in display units: angles in degrees,
    torques in N.cm; returns (values, axis label)."""
    if "." not in name:  # a result column: the scene's components are not looked at
        return np.asarray(values, dtype=float), name
    # Imported on use: the plot process draws a sweep's result columns
    # without fmpy and the engine (its start-up time; background).
    from ...engine.description import var_unit, variables
    from ...scene.model import ComponentVariables

    split = split_ref(name, ComponentVariables(scene.components))
    if split is None:
        return np.asarray(values, dtype=float), name
    inst, var = split
    v = variables(scene.components[inst].model_description).get(var)
    unit = var_unit(v) if v is not None else None
    values = np.asarray(values, dtype=float)
    if unit == "rad":
        return np.degrees(values), f"{name} (deg)"
    if unit == "rad/s":
        return np.degrees(values), f"{name} (deg/s)"
    if unit == "N.m":
        return values * 100.0, f"{name} (N.cm)"
    return values, f"{name} ({unit})" if unit else name


# Result columns carry their unit in the name's tail.
_UNIT_SUFFIXES = (("_s_per_day", "s/day"), ("_s_per_year", "s/year"), ("_rad_per_s", "rad/s"),
                  ("_per_s", "1/s"), ("_deg", "deg"), ("_rad", "rad"), ("_Nm", "N.m"), ("_Ncm", "N.cm"),
                  ("_s", "s"))


def unit_of(column: str) -> str | None:
    """The unit a result column's name ends with ("E_T_s_per_day" -> "s/day"), or None."""
    return next((u for suffix, u in _UNIT_SUFFIXES if column.endswith(suffix)), None)


def axis_label(columns: list[str]) -> str:
    """A y-axis label for result columns: their common unit, or the columns' names."""
    units = {unit_of(c) for c in columns}
    if len(units) == 1 and None not in units:
        return f"({units.pop()})" if len(columns) > 1 else f"{columns[0]} ({unit_of(columns[0])})"
    return ", ".join(columns)


PNG_DPI = 110


def save(fig, path: Path) -> None:
    """The figure as a PNG cropped to what is drawn: the bytes of savefig's
    bbox_inches="tight", with one layout of the figure instead of two
    (savefig draws it once, without output, only to find the box; the box
    found here from the artists' extents is the same)."""
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    box = "tight"
    if fig.get_layout_engine() is None:  # a layout engine moves the artists in that first draw: savefig's way
        fig.set_dpi(PNG_DPI)
        box = fig.get_tightbbox(FigureCanvasAgg(fig).get_renderer()).padded(matplotlib.rcParams["savefig.pad_inches"])
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=PNG_DPI, bbox_inches=box)
    write_bytes_atomic(path, buf.getvalue())


def draw_plot(scene, results: list[dict], out: Path, k: int) -> tuple[str, object]:
    """Plot k of the scene into `out`: ("written", file name, or the names
    of its pages), ("failed", {file, kind, error}) or ("empty", {file, kind,
    reason}). A plot kind returns a figure or a list of figures (pages).

    A scene run with --set overrides says so under the plot. A plot kind
    that raises is reported, not fatal: the data files are written all the
    same.
    """
    spec = scene.plots[k]
    kind = spec["kind"]
    name = spec.get("file") or f"plot{k + 1}_{kind}.png"
    try:
        figures = PLOTS[kind](scene, results, spec)
        if figures is None:
            return "empty", {"file": name, "kind": kind,
                             "reason": "nothing to draw: no point has a result for it (stalled or failed)"}
        if not isinstance(figures, list):
            figures = [figures]
        names = page_names(name, len(figures))
        for fig, page in zip(figures, names):
            if not fig.axes[0].get_title() and not fig._suptitle:
                fig.axes[0].set_title(spec.get("title", scene.title), fontsize=10)
            if scene.overrides:
                fig.text(0.01, 0.0, "--set " + "  ".join(scene.overrides), fontsize=7, color="0.35", va="top")
            save(fig, out / page)
    except Exception as e:  # a broken plot kind must not take the results with it
        return "failed", {"file": name, "kind": kind, "error": f"{type(e).__name__}: {' '.join(str(e).split())}"}
    return "written", names if len(names) > 1 else name


def page_names(name: str, n: int) -> list[str]:
    """The files of a plot's n pages: name, then <stem>_2.png, <stem>_3.png..."""
    stem = name[:-4]
    return [name] + [f"{stem}_{k}.png" for k in range(2, n + 1)]


def gather(outcomes: list[tuple[str, object]]) -> tuple[list[str], list[dict], list[dict]]:
    """Outcomes of draw_plot, in the scene's plot order, as (files written,
    plots that failed, plots with nothing to draw)."""
    written = [name for what, x in outcomes if what == "written" for name in ([x] if isinstance(x, str) else x)]
    failed = [x for what, x in outcomes if what == "failed"]
    empty = [x for what, x in outcomes if what == "empty"]
    return written, failed, empty


def column_names(spec: dict, key: str, default) -> list[str]:
    names = spec.get(key, default)
    return [] if names is None else [names] if isinstance(names, str) else list(names)


def unknown_column(scene, results: list[dict]) -> tuple[int, str, str, list[str]] | None:
    """The first column a plot names that no result has: (plot index, spec
    key, name, the columns there are), or None. Plots with nothing to draw
    at all (every point failed or stalled) are not judged: they say so
    themselves (``plots_not_drawn``)."""
    for i, spec in enumerate(scene.plots):
        keys, source = PLOT_COLUMNS.get(spec["kind"], ({}, "rows"))
        if not keys:
            continue
        there: set[str] = set()
        for r in results:
            if not r or "error" in r or r.get("result", {}).get("stalled") or r.get("result", {}).get("omitted"):
                continue  # a stalled point has no rates: it says nothing of the columns
            if source == "rows":
                there |= set(r.get("result", {})) | set(r.get("point", {}))
            else:
                there |= set(r.get(source, {}) or {})
        if not there:
            continue
        for key, default in keys.items():
            for name in column_names(spec, key, default):
                if name not in there:
                    return i, key, name, sorted(there)
    return None


def make_plots(scene, results: list[dict], out: Path) -> tuple[list[str], list[dict], list[dict]]:
    """Draw the scene's plots into `out`: (files written, plots that failed,
    plots with nothing to draw, e.g. when every sweep point stalled)."""
    return gather([draw_plot(scene, results, out, k) for k in range(len(scene.plots))])
