"""The basic plot kinds: a time series, a phase portrait, a sweep."""

from __future__ import annotations

import math

import numpy as np

from .registry import check_keys, display, pyplot, register


def _convert(t: dict) -> dict:
    out = check_keys(t, strings=("x", "title"))
    if "y" in t:
        check_keys({"y": t["y"]}, strings=(), string_lists=("y",))  # a string stays a string
    return out


@register("time_series", {"x", "y"}, _convert, run="series")
def time_series(scene, r, spec):
    series = r["series"]
    fig, ax = pyplot().subplots(figsize=(7, 4))
    x, xl = np.asarray(series["time"]), "time (s)"
    if spec.get("x") and spec["x"] != "time":
        x, xl = display(scene, spec["x"], series[spec["x"]])
    ys = spec.get("y") or [c for c in series if c != "time"]
    for y in [ys] if isinstance(ys, str) else ys:
        v, label = display(scene, y, series[y])
        ax.plot(x, v, label=label, lw=0.8)
    ax.set_xlabel(xl)
    ax.legend(loc="best", fontsize=8)
    return fig


@register("phase_portrait", {"x", "y"}, _convert, run="series")
def phase_portrait(scene, r, spec):
    series = r["series"]
    fig, ax = pyplot().subplots(figsize=(5, 5))
    xv, xl = display(scene, spec["x"], series[spec["x"]])
    yv, yl = display(scene, spec["y"], series[spec["y"]])
    ax.plot(xv, yv, lw=0.5)
    ax.set_xlabel(xl)
    ax.set_ylabel(yl)
    return fig


@register("sweep", {"x", "y"}, _convert)
def sweep(scene, results, spec):
    rows = [r for r in results if r and "result" in r and not r["result"].get("stalled")]
    if not rows:
        return None
    fig, ax = pyplot().subplots(figsize=(7, 4))
    x_key = spec.get("x", "amplitude_deg")
    ys = spec.get("y") or ["E_T_s_per_day", "E_C_s_per_day", "E_E_s_per_day"]
    ys = [ys] if isinstance(ys, str) else ys
    rows.sort(key=lambda r: r["result"].get(x_key) or 0.0)
    x = [r["result"].get(x_key) for r in rows]
    for y in ys:
        vals = [r["result"].get(y) for r in rows]
        ax.plot(x, [math.nan if v is None else v for v in vals], "o-", ms=3, label=y)
    ax.set_xlabel(x_key)
    ax.axhline(0.0, color="0.7", lw=0.5)
    ax.legend(loc="best", fontsize=8)
    return fig
