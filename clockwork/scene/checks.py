"""The checks every section of a scene file shares.

``Ctx`` turns a problem into one ``SceneError`` line naming the file, the
dotted key (or the ``--set`` argument that put it there) and what was
expected; the value converters check a TOML value against an FMU variable's
type, unit and range.
"""

from __future__ import annotations

import difflib
import os
from pathlib import Path

from ..fmi.description import (FLOAT32_MAX, INTEGER_TYPES, ArrayElement, int_range, shape_text, start_problem,
                                  var_limit, var_unit)
from ..fmi.description import variables as variables_of
from ..engine.names import instance_name_problem, split_ref
from ..engine.settings import SETTINGS, BadSetting
from ..errors import SceneError
from ..files import NotRegularFile, open_regular
from ..numbers import shorten
from .model import Component, ComponentVariables, show
from .units import UnitError, fmt, parse_quantity, to_seconds, to_unit

TOP_KEYS = ("scene", "components", "connections", "experiment", "master", "record", "analysis", "sweep", "plot",
            "inputs")


class Ctx:
    def __init__(self, path: Path, labels: dict[str, str | tuple[str, str]]):
        self.path = path
        # dotted key -> where its value came from: "--set x.y" for overridden
        # keys; (file, key) for a value another file gave (an FMU's
        # DefaultExperiment, an SSD's annotation)
        self.labels = labels

    def key(self, key: str) -> str:
        label = self.labels.get(key, key)
        return label[1] if isinstance(label, tuple) else label

    def where(self, key: str) -> tuple[object, str]:
        """(file, key) that an error about `key` names."""
        label = self.labels.get(key, key)
        return label if isinstance(label, tuple) else (self.path, label)

    def fail(self, key: str, detail: str) -> SceneError:
        return SceneError(detail, *self.where(key))

    def bad(self, key: str, value: object, expected: str) -> SceneError:
        path, shown = self.where(key)
        return SceneError(f"expected {expected}", path, f"{shown} = {show(value)}")

    def check_keys(self, table: dict, allowed, where: str, required=()) -> None:
        allowed = list(allowed)
        for k in table:
            if k not in allowed:
                full = f"{where}.{k}" if where else k
                close = difflib.get_close_matches(k, allowed, n=1)
                hint = f" (did you mean {close[0]}?)" if close else ""
                extra = ""
                if k in TOP_KEYS and where:
                    extra = f"; top-level key `{k}` must come before the first [table] header"
                allowed_s = ", ".join(sorted(allowed)) if allowed else "none"
                raise self.fail(full, f"unknown key{hint}; allowed: {allowed_s}{extra}")
        for k in required:
            if k not in table:
                if where:
                    raise self.fail(f"{where}.{k}", "missing required key")
                header = "components.<instance>" if k == "components" else k
                raise self.fail(k, f"missing required table [{header}]")

    def table(self, parent: dict, k: str, where: str, required: bool = False) -> dict | None:
        full = f"{where}.{k}" if where else k
        if k not in parent:
            if required:
                raise self.fail(full, "missing required table")
            return None
        t = parent[k]
        if not isinstance(t, dict):
            raise self.bad(full, t, "a table")
        return t

    def time(self, key: str, value: object) -> float:
        try:
            return to_seconds(value)
        except UnitError as e:
            raise self.bad(key, value, str(e)) from None


def read_bounded(path: Path, limit: int, noun: str, expected: str) -> bytes:
    """The bytes of a file clockwork reads whole (a scene, an input file), at
    most `limit` of them; SceneError naming it otherwise (`noun`: "scene
    file"; `expected`: what a directory is not, "a .toml scene file")."""
    try:
        # Refused before a byte is read: a FIFO, a socket, a device, a directory, a file over the bound.
        with open_regular(path, expected) as f:
            size = os.fstat(f.fileno()).st_size
            data = f.read(limit + 1) if size <= limit else b""
        if size > limit or len(data) > limit:
            raise SceneError(f"{max(size, len(data))} bytes: {article(noun)} {noun} is at most {limit} bytes", path)
    except NotRegularFile as e:
        raise SceneError(e.detail, path) from None
    except FileNotFoundError:
        raise SceneError(f"no such {noun}", path) from None
    except IsADirectoryError:
        raise SceneError(f"is a directory, expected {expected}", path) from None
    except OSError as e:
        raise SceneError(f"cannot read: {e.strerror}", path) from None
    return data


def instance_problem(name: object) -> str | None:
    """What is wrong with an instance name, in a scene file or an SSP
    (docs/scenes.md, "Components"), or None: the engine's name rule, and
    not the name of a scene section (--set master.step must mean the master)."""
    problem = instance_name_problem(name)
    if problem is None and name in TOP_KEYS:
        problem = f"the instance name {name} is reserved (it names a scene section)"
    return problem


def article(word: str) -> str:
    return "an" if word[:1] in "aeiou" else "a"


def names_of(variables: dict, *causalities: str) -> list[str]:
    """Names of the variables of these causalities (an array by its own name, not its elements')."""
    return [n for n, v in variables.items() if v.causality in causalities and not isinstance(v, ArrayElement)]


def settable_problem(v) -> str | None:
    """Why a scene, an SSP or --set cannot give `v` a value, or None: the
    parameters and inputs, and the variables the FMI standard lets a master
    set before initialization (an output or local with initial="exact" or
    "approx", FMI 1.0's start values: fmi.description.start_problem).
    A structural parameter is refused apart (STRUCTURAL)."""
    if v.causality in ("parameter", "input"):
        return None
    return start_problem(v)


SETTABLE = ('a parameter, an unconnected input or a variable with initial="exact" or "approx" (what the FMI '
            'standard lets a master set before initialization)')

STRUCTURAL = ("is a structural parameter (an array size): clockwork does not change structural parameters "
              "(FMI 3.0 configuration mode), the arrays keep the sizes of their start values")


def lookup(ctx: Ctx, key: str, variables: dict, name: str, instance: str, model: str, want: str):
    v = variables.get(name)
    if v is None:
        # (a name of thousands of characters: neither compared nor echoed whole)
        close = difflib.get_close_matches(name, list(variables), n=3) if len(name) <= 200 else []
        hint = f" (did you mean {' or '.join(close)}?)" if close else ""
        if want == "parameter":
            pool = names_of(variables, "parameter")
            listing = f"; parameters: {', '.join(pool)}"
        else:
            listing = ""
        raise ctx.fail(key, f"{instance} ({model}) has no variable {shorten(name, 80)}{hint}{listing}")
    return v


def convert_value(ctx: Ctx, key: str, value: object, v, md):
    """A TOML value -> the variable's type and unit, range-checked; an FMI
    3.0 array's value is a TOML array nested as its shape (row by row), each
    element checked (``key[i,j]`` in errors), kept as nested tuples."""
    shape = tuple(getattr(v, "shape", None) or ())
    if not shape:
        return _convert_scalar(ctx, key, value, v, md)

    def walk(x, dims: tuple[int, ...], index: tuple[int, ...]):
        if not dims:
            return _convert_scalar(ctx, f"{key}[{','.join(map(str, index))}]", x, v, md)
        if not isinstance(x, list) or len(x) != dims[0]:
            where = f"{key}[{','.join(map(str, index))}]" if index else key
            what = (f"an array of {dims[0]} values" if len(dims) == 1 else
                    f"an array of {dims[0]} arrays of {shape_text(dims[1:])} values")
            raise ctx.bad(where, x, f"{what} ({v.name} is {shape_text(shape)}, row by row)")
        return tuple(walk(y, dims[1:], (*index, i)) for i, y in enumerate(x))

    return walk(value, shape, ())


def _convert_scalar(ctx: Ctx, key: str, value: object, v, md):
    unit = var_unit(v)
    if v.type == "Real":
        try:
            x = to_unit(value, md, unit)
        except UnitError as e:
            raise ctx.bad(key, value, str(e)) from None
    elif v.type == "Enumeration" and isinstance(value, str):
        items = {i.name: int(i.value) for i in getattr(v.declaredType, "items", None) or []}
        if value not in items:
            raise ctx.bad(key, value, f"an integer or one of the items of {v.declaredType.name}: "
                                      f"{', '.join(items) or 'none'}")
        x = items[value]
    elif v.type == "Float32":
        try:
            x = to_unit(value, md, unit)
        except UnitError as e:
            raise ctx.bad(key, value, str(e)) from None
        if not abs(x) <= FLOAT32_MAX:
            raise ctx.bad(key, value, f"a Float32 value, in [-{FLOAT32_MAX:g}, {FLOAT32_MAX:g}]")
    elif v.type in INTEGER_TYPES:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ctx.bad(key, value, "an integer" + (" or an item name" if v.type == "Enumeration" else ""))
        x = value
        bounds = int_range(v.type)
        if bounds and not bounds[0] <= x <= bounds[1]:
            raise ctx.bad(key, value, f"an integer in [{bounds[0]}, {bounds[1]}] ({v.type})")
        items = {int(i.value): i.name for i in getattr(v.declaredType, "items", None) or []}
        if v.type == "Enumeration" and items and x not in items:
            raise ctx.bad(key, value, f"the value of an item of {v.declaredType.name}: "
                                      f"{', '.join(f'{k} ({n})' for k, n in items.items())}")
    elif v.type == "Boolean":
        if not isinstance(value, bool):
            raise ctx.bad(key, value, "true or false")
        return value
    elif v.type == "String":
        if not isinstance(value, str):
            raise ctx.bad(key, value, "a string")
        return value
    elif v.type == "Binary":
        try:
            bytes.fromhex(value if isinstance(value, str) else "?")
        except ValueError:
            raise ctx.bad(key, value, "a string of hexadecimal digits, two per byte (Binary)") from None
        return value
    else:
        raise ctx.fail(key, f"variables of type {v.type} cannot be set")
    lo, hi = var_limit(v, "min"), var_limit(v, "max")
    if (lo is not None and x < lo) or (hi is not None and x > hi):
        u = f" {unit}" if unit else ""
        if lo is not None and hi is not None:
            expected = f"a value in [{fmt(lo)}, {fmt(hi)}]{u}"
        elif lo is not None:
            expected = f"a value >= {fmt(lo)}{u}"
        else:
            expected = f"a value <= {fmt(hi)}{u}"
        if isinstance(value, str) and parse_quantity(value)[1] not in (None, unit):
            expected += f" (got {fmt(x)}{u})"
        raise ctx.bad(key, value, expected)
    return x


def master_value(ctx: Ctx, key: str, value: object):
    """A scene's master.<key> (from the file, --set, a sweep, an SSP
    annotation, clockwork.simulate) as MasterSettings holds it, checked by
    the field's declaration (engine.settings.Setting); a time may carry a
    unit. Refused in one line naming where the value came from."""
    full = f"master.{key}"
    spec = SETTINGS[key]
    x = ctx.time(full, value) if spec.kind == "time" else value
    try:
        return spec.accept(x)
    except BadSetting as e:
        raise ctx.bad(full, value, str(e)) from None


def parse_ref(ctx: Ctx, key: str, ref: object, components: dict[str, Component], what: str):
    split = split_ref(ref, ComponentVariables(components)) if isinstance(ref, str) else None
    if split is None:
        if isinstance(ref, str) and "." in ref.strip():
            component(ctx, key, components, ref.strip().partition(".")[0])  # no such component: name them
        raise ctx.bad(key, ref, f'"instance.variable" naming {what}')
    inst, var = split
    comp = component(ctx, key, components, inst)
    v = lookup(ctx, key, variables_of(comp.model_description), var, inst, comp.model_name,
               want="parameter" if what == "a parameter" else "any")
    return comp, v


def component(ctx: Ctx, key: str, components: dict[str, Component], inst: str) -> Component:
    """The component named `inst`; else SceneError at `key` with the names there are."""
    comp = components.get(inst)
    if comp is None:
        close = difflib.get_close_matches(inst, list(components), n=1)
        hint = f" (did you mean {close[0]}?)" if close else ""
        raise ctx.fail(key, f"no component named {inst}{hint}; components: {', '.join(components)}")
    return comp
