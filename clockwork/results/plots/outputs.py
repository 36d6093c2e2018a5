"""The default plot of a time series (kind ``outputs``): every recorded number,
readable however many there are and whatever their units.

Signals are grouped by unit onto stacked axes that share the time axis,
one legend per axes: a speed of 5000 deg/s does not flatten a current of
2 A on a shared y axis. Within a unit, signals whose sizes differ by more
than ``SPREAD`` get axes of their own (a 1e-3 A sensor beside a 10 A
supply); no axes holds more than ``MAX_LINES`` lines. Booleans share
axes marked false/true; discrete signals (integers, Booleans, Reals of
discrete variability) are drawn as steps. A page holds at most
``MAX_AXES`` axes (a screenful); more go to further pages, files
``<stem>_2.png``, ``<stem>_3.png``..., at most ``MAX_PAGES`` of them
(about 480 signals when a page is full): a run recording thousands of
outputs draws its first pages quickly instead of hundreds, and one note
says how many signals it left out. Each page is saved before the next is
built (``Pages``), so memory holds one page whatever the count. Angles, angular speeds and torques
are shown in the papers' units (deg, deg/s, N.cm), as every plot does.

``draw_outputs`` works on plain columns, so that ``clockwork plot DIR``
redraws a finished run from its timeseries.csv and the column
descriptions its summary.json keeps (``column_info``).
"""

from __future__ import annotations

import fnmatch
import math
from dataclasses import dataclass

import numpy as np

from ...engine.names import split_ref
from .registry import MAX_TITLE, check_keys, legend, plain, register, subplots

MAX_PAGES = 10  # per drawing: the signals past them are left out, with a note
MAX_AXES = 6  # per page: with the title and the time axis, about 950 pixels high
MAX_LINES = 8  # per axes: a legend that stays beside its axes
SPREAD = 30.0  # one unit, sizes further apart than this: separate axes (a signal fills at least 1/30 of its axes)
_HEIGHT_IN = 1.35  # per axes
# Units shown as the papers show them: (unit, factor, shown unit)
_DISPLAY = {"rad": (180.0 / math.pi, "deg"), "rad/s": (180.0 / math.pi, "deg/s"), "N.m": (100.0, "N.cm")}


@dataclass
class Column:
    name: str  # as labelled in the legend
    values: np.ndarray  # in the shown unit
    unit: str  # shown unit; "" for none
    kind: str  # "real", "discrete" or "boolean"

    @property
    def size(self) -> float:
        """The largest magnitude (0 for no finite value)."""
        finite = self.values[np.isfinite(self.values)]
        return float(np.max(np.abs(finite))) if finite.size else 0.0


def column_info(scene, names) -> dict[str, dict]:
    """{column: {"unit", "type", "variability"}} of recorded "instance.variable"
    columns (kept in summary.json for `clockwork plot`)."""
    # Imported on use: the plot process starts without the engine and fmpy (background).
    from ...fmi.description import var_unit, variables

    found = {n: variables(c.model_description) for n, c in scene.components.items()}
    out = {}
    for name in names:
        split = split_ref(name, found)
        v = found[split[0]].get(split[1]) if split else None
        if v is not None:
            out[name] = {"unit": var_unit(v), "type": v.type, "variability": v.variability}
    return out


def recorded_view(scene, names) -> tuple[dict[str, dict], str | None]:
    """(column_info of the recorded `names`, the one component's name or
    None): what the plot of a run's outputs reads of the scene. An early plot
    process gets it computed by the run (background._SceneOnDemand's
    ``recorded_view``), which spares it fmpy, the engine and the scene."""
    given = getattr(scene, "recorded_view", None)
    if given is not None and all(n in given[2] for n in names):
        info, strip, _ = given
        return {n: info[n] for n in names if n in info}, strip
    strip = next(iter(scene.components)) if len(scene.components) == 1 else None
    return column_info(scene, names), strip


def _kind(info: dict) -> str:
    from ...fmi.types import INTEGER_TYPES

    if info.get("type") == "Boolean":
        return "boolean"
    if info.get("type") in INTEGER_TYPES or info.get("variability") in ("discrete", "fixed", "tunable", "constant"):
        return "discrete"
    return "real"


def columns(series: dict, info: dict, only=None, strip: str | None = None, patterns: bool = False) -> list[Column]:
    """The numeric columns of a series (time aside) as Columns, in order;
    `only`: the names to keep (with `patterns`, shell patterns too, matched
    against the full name and the label); `strip`: an instance prefix left
    out of the labels (a scene of one component)."""
    from ...fmi.types import TEXT_TYPES

    out = []
    for name, values in series.items():
        if name == "time":
            continue
        meta = info.get(name, {})
        if meta.get("type") in TEXT_TYPES or any(isinstance(x, str) for x in values):
            continue
        label = name[len(strip) + 1:] if strip and name.startswith(strip + ".") else name
        # with `patterns` (plot --only), an FMI 3.0 array's name stands for its elements' columns, as in [record]
        whole = (name.partition("[")[0], label.partition("[")[0]) if patterns and name.endswith("]") else ()
        if only and name not in only and not (patterns and any(
                fnmatch.fnmatchcase(name, p) or fnmatch.fnmatchcase(label, p) or p in whole for p in only)):
            continue
        unit = meta.get("unit") or ""
        factor, shown = _DISPLAY.get(unit, (1.0, unit))
        arr = np.asarray([math.nan if x is None else x for x in values], dtype=float)
        out.append(Column(label, arr * factor if factor != 1.0 else arr, shown, _kind(meta)))
    return out


def group(cols: list[Column]) -> list[list[Column]]:
    """Columns onto axes: by unit (Booleans together), split where sizes
    differ by more than SPREAD, at most MAX_LINES per axes; units in the
    order they first come."""
    units: dict[tuple[str, bool], list[Column]] = {}
    for c in cols:
        units.setdefault(("", True) if c.kind == "boolean" else (c.unit, False), []).append(c)
    axes = []
    for members in units.values():
        if members[0].kind == "boolean":
            clusters = [members]
        else:
            ranked = sorted(members, key=lambda c: -c.size)
            clusters: list[list[Column]] = []
            zero = [c for c in ranked if c.size == 0.0]
            for c in ranked:
                if c.size == 0.0:
                    continue
                if clusters and clusters[-1][0].size <= SPREAD * c.size:
                    clusters[-1].append(c)
                else:
                    clusters.append([c])
            if zero:  # all zero: flat wherever drawn, kept with the smallest signals
                if not clusters:
                    clusters.append([])
                clusters[-1].extend(zero)
            order = {id(c): k for k, c in enumerate(members)}
            clusters = [sorted(cl, key=lambda c: order[id(c)]) for cl in clusters]
        for cl in clusters:
            axes += [cl[k:k + MAX_LINES] for k in range(0, len(cl), MAX_LINES)]
    return axes


class Pages:
    """The pages of a drawing, each figure built when iterated to (the
    caller saves it and lets it go before the next is built); `count`:
    how many; `note`: what was left out past MAX_PAGES, or None."""

    def __init__(self, time, cols: list[Column], title: str, max_pages: int | None = None):
        max_pages = MAX_PAGES if max_pages is None else max_pages
        axes_groups = group(cols)
        pages = [axes_groups[k:k + MAX_AXES] for k in range(0, len(axes_groups), MAX_AXES)]
        self.note = None
        if len(pages) > max_pages:
            drawn = sum(len(members) for page in pages[:max_pages] for members in page)
            self.note = (f"drew {drawn} of the {len(cols)} recorded numbers on {max_pages} pages, the most a "
                         f"drawing has; the other {len(cols) - drawn} are in timeseries.csv")
            pages = pages[:max_pages]
        self.count = len(pages)
        self._args = (time, pages, title)

    def __iter__(self):
        return _draw_pages(*self._args)


def draw_outputs(time, cols: list[Column], title: str) -> list:
    """The figures (pages) of these columns against time (s), all built (tests)."""
    return list(Pages(time, cols, title))


def output_pages(time, cols: list[Column], title: str) -> Pages:
    """The pages of these columns against time (s), built one at a time."""
    return Pages(time, cols, title)


def _draw_pages(time, pages: list, title: str):
    t = np.asarray(time, dtype=float)
    for p, page in enumerate(pages):
        fig, axs = subplots(len(page), 1, figsize=(10, 0.9 + _HEIGHT_IN * len(page)), sharex=True, squeeze=False)
        for ax, members in zip(axs[:, 0], page):
            lines = []
            for c in members:
                style = {"drawstyle": "steps-post"} if c.kind != "real" else {}
                lines += ax.plot(t, c.values.astype(float), lw=1.0, **style)
            if members[0].kind == "boolean":
                ax.set_yticks([0, 1], ["false", "true"])
                ax.set_ylim(-0.15, 1.15)
                ax.set_ylabel("Boolean", fontsize=8)
            else:
                ax.set_ylabel(plain(members[0].unit) if members[0].unit else "(no unit)", fontsize=8)
            ax.tick_params(labelsize=8)
            ax.grid(True, lw=0.3, color="0.85")
            legend(ax, lines, [plain(c.name) for c in members], loc="upper left", bbox_to_anchor=(1.01, 1.0),
                   fontsize=8, frameon=False, borderaxespad=0.0)
        axs[-1, 0].set_xlabel("time (s)", fontsize=9)
        page_note = f"  (page {p + 1} of {len(pages)})" if len(pages) > 1 else ""
        fig.suptitle(plain(title, MAX_TITLE) + page_note, fontsize=10)
        fig.tight_layout()
        yield fig


def _convert(t: dict) -> dict:
    return check_keys(t, strings=("title",), string_lists=("y",))


@register("outputs", {"y"}, _convert, run="series", columns={"y": None})
def outputs(scene, r, spec):
    """Every recorded number (or the recorded columns `y` names), grouped
    by unit: a list of pages."""
    series = r["series"]
    info, strip = recorded_view(scene, [n for n in series if n != "time"])
    cols = columns(series, info, spec.get("y"), strip)
    return output_pages(series["time"], cols, spec.get("title", scene.title)) if cols else None
