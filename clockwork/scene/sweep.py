"""The [sweep] section: axes over parameters, master settings or the
experiment, combined as a grid or zipped."""

from __future__ import annotations

import difflib
import math

import numpy as np

from ..fmi.description import INTEGER_TYPES, REAL_TYPES, element_names
from ..errors import SceneError
from .checks import Ctx, article, convert_value, master_value, parse_ref, settable_problem
from .model import Component, Sweep, SweepAxis, show

MAX_POINTS = 1_000_000  # at a millisecond a point, a quarter of an hour; more is a slip
_SWEEPABLE_MASTER = ("step", "min_step", "max_step", "extrapolation", "iterations", "iteration_tolerance",
                     "event_time_tolerance", "event_indicator_tolerance", "richardson_tolerance",
                     "order", "event_location", "event_prediction", "richardson", "algebraic_loops")


def parse_sweep(ctx: Ctx, t: dict | None, components: dict[str, Component], connected: set) -> Sweep | None:
    if t is None:
        return None
    ctx.check_keys(t, ("mode", "axes"), "sweep", required=("axes",))
    mode = t.get("mode", "grid")
    if mode not in ("grid", "zip"):
        raise ctx.bad("sweep.mode", mode, '"grid" or "zip"')
    axes_t = t["axes"]
    if not isinstance(axes_t, list) or not axes_t:
        raise ctx.bad("sweep.axes", axes_t, "a non-empty array of axis tables")
    axes = []
    for i, a in enumerate(axes_t):
        where = f"sweep.axes[{i}]"
        if not isinstance(a, dict):
            raise ctx.bad(where, a, "a table { parameter = ..., values = [...] }")
        ctx.check_keys(a, ("parameter", "values", "start", "stop", "num", "spacing"), where, required=("parameter",))
        pkey = f"{where}.parameter"
        ref = a["parameter"]
        if isinstance(ref, str) and ref.split(".", 1)[0] in ("master", "experiment") and ref.split(".", 1)[0] not in components:
            owner, name = ref.split(".", 1)
            allowed = _SWEEPABLE_MASTER if owner == "master" else ("start", "stop")
            if name not in allowed:
                close = difflib.get_close_matches(name, allowed, n=1)
                hint = f" (did you mean {owner}.{close[0]}?)" if close else ""
                raise ctx.bad(pkey, ref, f"a sweepable {owner} key{hint}: {', '.join(allowed)}")
            if owner == "master":
                def convert(k, x, name=name):
                    return _master_value_at(ctx, k, name, x)
            else:
                def convert(k, x):
                    return ctx.time(k, x)
            param = (owner, name)
            var = None
        else:
            comp, var = parse_ref(ctx, pkey, ref, components, "a parameter")
            if var.causality == "structuralParameter" or settable_problem(var):
                why = settable_problem(var) or "a structural parameter (an array size), which clockwork does not change"
                raise ctx.fail(pkey, f"{ref} is {article(var.causality)} {var.causality}, not a parameter ({why})")
            if getattr(var, "shape", None):
                raise ctx.fail(pkey, f"{ref} is an array: sweep one of its elements (e.g. "
                                     f"{comp.name}.{element_names(var)[0]})" if element_names(var) else
                               f"{ref} is an empty array")
            if var.causality == "input" and (comp.name, var.name) in connected:
                raise ctx.fail(pkey, f"{ref} is a connected input; it cannot be swept")
            md = comp.model_description

            def convert(k, x, var=var, md=md):
                return convert_value(ctx, k, x, var, md)
            param = (comp.name, var.name)
        if param in [ax.parameter for ax in axes]:
            raise ctx.fail(pkey, f"{ref} is swept twice")
        has_values = "values" in a
        has_range = any(k in a for k in ("start", "stop", "num", "spacing"))
        if has_values == has_range:
            raise ctx.fail(where, "expected either values = [...] or start, stop, num (and spacing)")
        if has_values:
            vals = a["values"]
            if not isinstance(vals, list) or not vals:
                raise ctx.bad(f"{where}.values", vals, "a non-empty array of values")
            values = tuple(convert(f"{where}.values[{j}]", x) for j, x in enumerate(vals))
        else:
            for k in ("start", "stop", "num"):
                if k not in a:
                    raise ctx.fail(f"{where}.{k}", "missing required key (with start/stop/num)")
            num = a["num"]
            if isinstance(num, bool) or not isinstance(num, int) or not 1 <= num <= MAX_POINTS:
                raise ctx.bad(f"{where}.num", num, f"an integer from 1 to {MAX_POINTS}")
            spacing = a.get("spacing", "linear")
            if spacing not in ("linear", "log"):
                raise ctx.bad(f"{where}.spacing", spacing, '"linear" or "log"')
            numeric = var is None or var.type in REAL_TYPES or var.type in INTEGER_TYPES and var.type != "Enumeration"
            if not numeric:
                raise ctx.fail(where, f"{ref} is {var.type}: list its values instead of start/stop/num")
            lo = _range_end(ctx, f"{where}.start", a["start"], var, convert)
            hi = _range_end(ctx, f"{where}.stop", a["stop"], var, convert)
            if spacing == "log" and not (lo > 0 and hi > 0):
                bad_k = "start" if not lo > 0 else "stop"
                raise ctx.bad(f"{where}.{bad_k}", a[bad_k], "a value > 0 for log spacing")
            grid = np.geomspace(lo, hi, num) if spacing == "log" else np.linspace(lo, hi, num)
            if num == 1:
                grid = np.array([lo])
            seq = [float(x) for x in grid]
            if (var is not None and var.type in INTEGER_TYPES) or param in (("master", "iterations"), ("master", "extrapolation")):
                ints = [round(x) for x in seq]
                if any(abs(x - r) > 1e-9 * max(1.0, abs(x)) for x, r in zip(seq, ints)):
                    odd = [x for x, r in zip(seq, ints) if abs(x - r) > 1e-9 * max(1.0, abs(x))]
                    raise ctx.fail(where, f"{ref} is an integer but start/stop/num give non-integer values "
                                          f"({', '.join(f'{x:g}' for x in odd[:3])}{', ...' if len(odd) > 3 else ''})")
                seq = ints
            values = tuple(convert(f"{where}.start", x) for x in seq)
        axes.append(SweepAxis(param, values))
    if mode == "zip":
        n = len(axes[0].values)
        for i, ax in enumerate(axes):
            if len(ax.values) != n:
                raise ctx.fail(f"sweep.axes[{i}]", f"zip mode needs axes of equal length: "
                                                   f"{len(ax.values)} values here, {n} in sweep.axes[0]")
    total = len(axes[0].values) if mode == "zip" else math.prod(len(ax.values) for ax in axes)
    if total > MAX_POINTS:
        raise ctx.fail("sweep", f"{total} points: a sweep has at most {MAX_POINTS}")
    _refuse_repeated_points(ctx, mode, axes)
    return Sweep(mode, tuple(axes))


def _refuse_repeated_points(ctx: Ctx, mode: str, axes: list[SweepAxis]) -> None:
    """A point given twice would run twice for the same result: refused, not
    merged, since it is a slip (a copied value, start = stop) that changes
    the sweep's shape, and merging would shift the rows against the values."""
    rows = list(zip(*(ax.values for ax in axes))) if mode == "zip" else None
    groups = [(f"sweep.axes[{i}]", [(v,) for v in ax.values]) for i, ax in enumerate(axes)] if rows is None \
        else [("sweep.axes", rows)]
    for where, items in groups:
        first: dict = {}
        for j, item in enumerate(items):
            k = tuple((type(x).__name__, x) for x in item)
            if k in first:
                n = len(items) - len(set(map(lambda it: tuple((type(x).__name__, x) for x in it), items)))
                what = "value" if rows is None else "point (one value of each axis)"
                raise ctx.fail(where, f"the {what} #{j} ({', '.join(map(show, item))}) repeats #{first[k]}"
                                      f"{f' ({n} repeats in all)' if n > 1 else ''}: expected each {what} once "
                                      "(a repeated point would run again for the same result)")
            first[k] = j


def _master_value_at(ctx: Ctx, key: str, name: str, value: object):
    """Like _master_value but errors name `key` (a sweep entry) instead of master.<name>."""
    try:
        return master_value(ctx, name, value)
    except SceneError as e:
        path, shown = ctx.where(key)
        raise SceneError(e.detail, path, f"{shown} = {show(value)}") from None


def _range_end(ctx: Ctx, key: str, value: object, var, convert) -> float:
    """A sweep start/stop in the variable's unit (validated against its range)."""
    x = convert(key, value)
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        raise ctx.bad(key, value, "a number")
    return float(x)
