"""The basic plot kinds: a time series, a phase portrait, a sweep."""

from __future__ import annotations

import math

import numpy as np

from .registry import axis_label, check_keys, display, legend, plain, register, subplots, title_of


def _convert(t: dict) -> dict:
    out = check_keys(t, strings=("x", "title"))
    if "y" in t:
        check_keys({"y": t["y"]}, strings=(), string_lists=("y",))  # a string stays a string
    return out


@register("time_series", {"x", "y"}, _convert, run="series", columns={"x": None, "y": None})
def time_series(scene, r, spec):
    series = r["series"]
    fig, ax = subplots(figsize=(7, 4))
    x, xl = np.asarray(series["time"]), "time (s)"
    if spec.get("x") and spec["x"] != "time":
        x, xl = display(scene, spec["x"], series[spec["x"]])
    ys = spec.get("y") or [c for c in series if c != "time"]
    labels, lines = [], []
    for y in [ys] if isinstance(ys, str) else ys:
        v, label = display(scene, y, series[y])
        lines += ax.plot(x, v, lw=0.8)
        labels.append(label)
    marks, marked = [], []
    failed = r.get("failed")
    if failed and failed.get("time_s") is not None and (not spec.get("x") or spec["x"] == "time"):
        marks = [ax.axvline(failed["time_s"], color="C3", lw=0.8, ls="--")]
        marked = [f"failed at t = {failed['time_s']:.6g} s ({plain(failed.get('instance') or 'the master')})"]
        ax.set_title(f"{title_of(scene, spec)} (failed at t = {failed['time_s']:.6g} s)", fontsize=10)
    ax.set_xlabel(xl)
    units = {lb[lb.rfind("(") + 1:-1] for lb in labels if lb.endswith(")")}
    ax.set_ylabel(f"value ({units.pop()})" if len(units) == 1 and len(labels) > 1 else
                  labels[0] if len(labels) == 1 else "value (units in the legend)")
    legend(ax, lines + marks, labels + marked, loc="best", fontsize=8)
    return fig


@register("phase_portrait", {"x", "y"}, _convert, run="series", columns={"x": None, "y": None})
def phase_portrait(scene, r, spec):
    series = r["series"]
    fig, ax = subplots(figsize=(5, 5))
    xv, xl = display(scene, spec["x"], series[spec["x"]])
    yv, yl = display(scene, spec["y"], series[spec["y"]])
    ax.plot(xv, yv, lw=0.5)
    ax.set_xlabel(xl)
    ax.set_ylabel(yl)
    return fig


@register("sweep", {"x", "y"}, _convert, columns={"x": "amplitude_deg", "y": ["E_T_s_per_day", "E_C_s_per_day", "E_E_s_per_day"]})
def sweep(scene, results, spec):
    """Result columns against a sweep axis (`x`: an axis "instance.variable" or
    a result column); text and true/false axes are drawn as categories."""
    rows = [r for r in results if r and "result" in r and not r["result"].get("stalled")]
    if not rows:
        return None
    fig, ax = subplots(figsize=(7, 4))
    x_key = spec.get("x", "amplitude_deg")
    ys = spec.get("y") or ["E_T_s_per_day", "E_C_s_per_day", "E_E_s_per_day"]
    ys = [ys] if isinstance(ys, str) else ys

    def x_of(r):
        return r["point"][x_key] if x_key in r.get("point", {}) else r["result"].get(x_key)

    xs = [x_of(r) for r in rows]
    numeric = all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in xs)
    if numeric:
        order = sorted(range(len(rows)), key=lambda i: xs[i])
        rows = [rows[i] for i in order]
        xs, xl = display(scene, x_key, [xs[i] for i in order])  # angles in deg, torques in N.cm
    else:
        xs, xl = [plain(str(x).lower() if isinstance(x, bool) else x) for x in xs], plain(x_key)
    ax.set_xlabel(xl)
    lines = []
    for y in ys:
        vals = [r["result"].get(y) for r in rows]
        lines += ax.plot(xs, [math.nan if v is None else v for v in vals], "o-" if numeric else "o", ms=3)
    ax.set_ylabel(axis_label(ys))
    ax.axhline(0.0, color="0.7", lw=0.5)
    legend(ax, lines, [plain(y) for y in ys], loc="best", fontsize=8)
    return fig
