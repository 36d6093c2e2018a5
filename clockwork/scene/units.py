"""Quantities written as "<number> <unit>" and their conversion.

A variable's allowed units come from its FMU: the variable's own unit, its
display units, and every unit of the FMU's UnitDefinitions whose BaseUnit
has the same SI exponents (with that unit's display units). FMI 2.0 defines

    value_in_base_SI = baseUnit.factor * value_in_unit + baseUnit.offset
    value_in_display = displayUnit.factor * value_in_unit + displayUnit.offset

Experiment and master times use the fixed table TIME_UNITS instead.
"""

from __future__ import annotations

import math
import re

TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "min": 60.0, "h": 3600.0, "d": 86400.0}
ANGLE_UNITS = {"rad": 1.0, "mrad": 1e-3, "deg": math.pi / 180.0}

_EXPONENTS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
_NUMBER = r"[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?|[-+]?(?:inf|nan)"
_QUANTITY = re.compile(rf"^\s*({_NUMBER})(?:\s*(\S.*?))?\s*$")


class UnitError(ValueError):
    """str() says what was expected, e.g. 'a unit of rad: rad, deg'."""


def fmt(x: float) -> str:
    """Short exact rendering: integral floats without '.0', else repr."""
    if isinstance(x, float) and x.is_integer() and abs(x) < 1e16:
        return str(int(x))
    return repr(x)


def parse_quantity(value: object) -> tuple[float, str | None]:
    """(number, unit or None) from a TOML number or a '<number> [unit]' string."""
    if isinstance(value, bool):
        raise UnitError("a number or a string '<number> <unit>'")
    if isinstance(value, (int, float)):
        try:
            number = float(value)
        except OverflowError:  # an integer with hundreds of digits
            raise UnitError("a finite number") from None
        unit = None
    elif isinstance(value, str):
        m = _QUANTITY.match(value)
        if not m:
            raise UnitError("a number or a string '<number> <unit>'")
        number = float(m.group(1))
        unit = m.group(2)
    else:
        raise UnitError("a number or a string '<number> <unit>'")
    if not math.isfinite(number):
        raise UnitError("a finite number")
    return number, unit


def _scaled(value: object, units: dict[str, float], what: str, base: str) -> float:
    """A bare number in the `base` unit, or '<number> <unit>' with a unit of `units`."""
    try:
        number, unit = parse_quantity(value)
    except UnitError:
        raise UnitError(f"{what}: a number in {base} or '<number> <unit>' with unit {', '.join(units)}") from None
    if unit is None:
        return number
    if unit not in units:
        raise UnitError(f"{what} unit: one of {', '.join(units)}")
    scaled = number * units[unit]
    if not math.isfinite(scaled):
        raise UnitError(f"{what} that is a finite number in {base}")
    return scaled


def to_seconds(value: object) -> float:
    """A time, s: bare number in s, or a string with a unit of TIME_UNITS."""
    return _scaled(value, TIME_UNITS, "a time", "s")


def to_radians(value: object) -> float:
    """An angle, rad: bare number in rad, or a string with a unit of ANGLE_UNITS."""
    return _scaled(value, ANGLE_UNITS, "an angle", "rad")


def _base(unit_def) -> tuple | None:
    b = getattr(unit_def, "baseUnit", None)
    if b is None:
        return None
    return tuple(int(getattr(b, e, 0) or 0) for e in _EXPONENTS), float(b.factor), float(b.offset)


def unit_conversions(model_description, unit: str) -> dict[str, tuple[float, ...]]:
    """{unit name: conversion} for the names a value in `unit` may be given in.

    A conversion (fd, od, fu, ou, ft, ot) maps x to
    (fu * ((x - od) / fd) + ou - ot) / ft: display unit -> its unit -> SI
    base -> `unit` (see apply_conversion). Identity steps are exact, so
    "99.4 cm" gives 0.994 m, not 0.9940000000000001. The first entry is
    `unit` itself, then its display units, then the other units with the
    same BaseUnit exponents and their display units; a name defined twice
    keeps its first (closest) meaning.
    """
    defs = {u.name: u for u in getattr(model_description, "unitDefinitions", None) or []}
    conv: dict[str, tuple[float, ...]] = {unit: (1.0, 0.0, 1.0, 0.0, 1.0, 0.0)}
    target = defs.get(unit)
    if target is None:
        return conv
    for d in target.displayUnits or []:
        conv.setdefault(d.name, (float(d.factor), float(d.offset), 1.0, 0.0, 1.0, 0.0))
    tb = _base(target)
    if tb is None:
        return conv
    t_exp, ft, ot = tb
    for name, udef in defs.items():
        ub = _base(udef)
        if name == unit or ub is None or ub[0] != t_exp:
            continue
        _, fu, ou = ub
        conv.setdefault(name, (1.0, 0.0, fu, ou, ft, ot))
        for d in udef.displayUnits or []:
            conv.setdefault(d.name, (float(d.factor), float(d.offset), fu, ou, ft, ot))
    return conv


def apply_conversion(c: tuple[float, ...], x: float) -> float:
    fd, od, fu, ou, ft, ot = c
    return (fu * ((x - od) / fd) + ou - ot) / ft


def to_unit(value: object, model_description, unit: str | None) -> float:
    """Convert a TOML number or '<number> <unit>' string to a value in `unit`.

    A bare number is taken to be in `unit` already; a dimensionless
    variable (unit None) takes bare numbers only.
    """
    number, given = parse_quantity(value)
    if given is None or given == unit:
        return number
    if not unit:
        raise UnitError("a bare number (the variable is dimensionless)")
    conv = unit_conversions(model_description, unit)
    if given not in conv:
        raise UnitError(f"a unit of {unit}: one of {', '.join(conv)}")
    x = apply_conversion(conv[given], number)
    if not math.isfinite(x):
        raise UnitError(f"a value that is a finite number in {unit}")
    return x


def link_conversion(src_md, src_unit: str, dst_md, dst_unit: str) -> tuple[float, float] | None:
    """(factor, offset) that turns a value in `src_unit` (declared by the
    FMU `src_md`) into `dst_unit` (declared by `dst_md`): each unit's
    BaseUnit in its own FMU's UnitDefinitions gives its SI exponents,
    factor and offset, so spellings such as "Nm/A" and "N.m/A" meet. None
    when either unit is undefined there or their exponents differ."""
    if src_unit == dst_unit:
        return 1.0, 0.0
    defs = [{u.name: u for u in getattr(md, "unitDefinitions", None) or []} for md in (src_md, dst_md)]
    su, du = defs[0].get(src_unit), defs[1].get(dst_unit)
    sb, db = (_base(u) if u is not None else None for u in (su, du))
    if sb is None or db is None or sb[0] != db[0]:
        return None
    (_, fs, os_), (_, fd, od) = sb, db
    # value_SI = fs * x + os_;  y = (value_SI - od) / fd
    return fs / fd, (os_ - od) / fd
