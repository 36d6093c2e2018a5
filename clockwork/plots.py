"""PNG plots of a scene's results, in the units of the papers (deg, s/day)."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .results import _write_atomic as write_bytes_atomic  # noqa: E402


def _display(scene, name: str, values):
    """Angles in degrees, torques in N.cm; returns (values, label)."""
    if "." not in name:
        return np.asarray(values, dtype=float), name
    inst, var = name.split(".", 1)
    comp = scene.components.get(inst)
    unit = None
    if comp is not None:
        for v in comp.model_description.modelVariables:
            if v.name == var:
                unit = v.unit or (v.declaredType.unit if v.declaredType else None)
    values = np.asarray(values, dtype=float)
    if unit == "rad":
        return np.degrees(values), f"{name} (deg)"
    if unit == "rad/s":
        return np.degrees(values), f"{name} (deg/s)"
    if unit == "N.m":
        return values * 100.0, f"{name} (N.cm)"
    return values, f"{name} ({unit})" if unit else name


def _save(fig, path: Path) -> None:
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    write_bytes_atomic(path, buf.getvalue())


PLOTS: dict = {}


def register(kind: str, keys: set[str] | frozenset[str] | None = None, convert=None):
    """Register ``f(scene, results, spec) -> Figure | None`` as plot kind `kind`.

    Passing `keys` also teaches the scene validator the kind's keys.
    """
    def wrap(func):
        PLOTS[kind] = func
        if keys is not None:
            from .scene import register_plot

            register_plot(kind, set(keys) | {"title", "file"}, convert)
        return func

    return wrap


@register("time_series")
def time_series(scene, results, spec):
    if not (results and results[0] and "series" in results[0]):
        return None
    series = results[0]["series"]
    fig, ax = plt.subplots(figsize=(7, 4))
    x, xl = np.asarray(series["time"]), "time (s)"
    if spec.get("x") and spec["x"] != "time":
        x, xl = _display(scene, spec["x"], series[spec["x"]])
    ys = spec.get("y") or [c for c in series if c != "time"]
    for y in [ys] if isinstance(ys, str) else ys:
        v, label = _display(scene, y, series[y])
        ax.plot(x, v, label=label, lw=0.8)
    ax.set_xlabel(xl)
    ax.legend(loc="best", fontsize=8)
    return fig


@register("phase_portrait")
def phase_portrait(scene, results, spec):
    if not (results and results[0] and "series" in results[0]):
        return None
    series = results[0]["series"]
    fig, ax = plt.subplots(figsize=(5, 5))
    xv, xl = _display(scene, spec["x"], series[spec["x"]])
    yv, yl = _display(scene, spec["y"], series[spec["y"]])
    ax.plot(xv, yv, lw=0.5)
    ax.set_xlabel(xl)
    ax.set_ylabel(yl)
    return fig


@register("sweep")
def sweep(scene, results, spec):
    rows = [r for r in results if r and "result" in r and not r["result"].get("stalled")]
    if not rows:
        return None
    fig, ax = plt.subplots(figsize=(7, 4))
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


def make_plots(scene, results: list[dict], out: Path) -> list[str]:
    written = []
    for k, spec in enumerate(scene.plots):
        kind = spec["kind"]
        name = spec.get("file") or f"plot{k + 1}_{kind}.png"
        fig = PLOTS[kind](scene, results, spec)
        if fig is None:
            continue
        if not fig.axes[0].get_title():
            fig.axes[0].set_title(spec.get("title", scene.title), fontsize=10)
        _save(fig, out / name)
        written.append(name)
    return written
