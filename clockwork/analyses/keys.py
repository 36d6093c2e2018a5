"""Converters of analysis-table values, shared by every analysis kind.

Each converter takes the key (for the message) and the raw TOML value,
returns the value in SI units, and raises ``Invalid(key, expected)`` for a
bad one. Angles take "<n> deg" (or rad), times "<n> s" (or ms, min, ...).

Every key a kind declares is a ``Key``: the converter with its bound, the
range its physics and the FMUs accept, as a line of docs/scenes.md states it
(``Key.bound``; tests/test_analysis_keys.py holds the two together). What
depends on the scene (the FMU's declared range of the parameter a key moves,
the experiment's span, the master's step) a kind checks in its
``register(..., check=)`` function at every sweep point, with
``within_fmu`` for the FMU ranges; the Key's ``also`` says what that check
holds it to.
"""

from __future__ import annotations

import math
from typing import Callable

from ..fmi.description import var_limit, var_unit
from ..fmi.description import variables as variables_of
from ..scene.kinds import Invalid
from ..scene.units import UnitError, parse_quantity, to_radians, to_seconds

TORQUE_UNITS = {"N.m": 1.0, "J": 1.0, "N.cm": 1e-2, "N.mm": 1e-3}
MAX_COUNT = 10_000_000  # a count an analysis takes (periods, samples): each costs steps or memory
MAX_LIST = 1000  # entries of a list an analysis runs one co-simulation per entry of


class Key:
    """An analysis key's converter and its bound: ``Key(key, value)``
    converts; `bound` is what it accepts on its own, `also` what the kind's
    check adds from the scene (empty: nothing)."""

    def __init__(self, convert: Callable[[str, object], object], bound: str, also: str = ""):
        self.convert, self.bound, self.also = convert, bound, also

    def __call__(self, key: str, value):
        return self.convert(key, value)

    @property
    def stated(self) -> str:
        """The bound as docs/scenes.md states it."""
        return f"{self.bound}; {self.also}" if self.also else self.bound


def _interval(lo, hi, lo_open: bool, hi_open: bool, unit: str = "") -> str:
    left = "(" if lo_open or lo is None else "["
    right = ")" if hi_open or hi is None else "]"
    text = f"{left}{'-inf' if lo is None else f'{lo:g}'}, {'inf' if hi is None else f'{hi:g}'}{right}"
    return f"{text} {unit}".rstrip()


def _inside(x: float, lo, hi, lo_open: bool, hi_open: bool) -> bool:
    if lo is not None and (x < lo or (lo_open and x == lo)):
        return False
    if hi is not None and (x > hi or (hi_open and x == hi)):
        return False
    return True


def _real(v) -> float | None:
    """A TOML number as a finite float, else None."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    try:
        x = float(v)
    except OverflowError:  # an integer of hundreds of digits
        return None
    return x if math.isfinite(x) else None


def number(lo=None, hi=None, *, lo_open: bool = False, hi_open: bool = False, unit: str = "",
           also: str = "") -> Key:
    """A bare number in the interval (in `unit`, which only the text names)."""
    where = _interval(lo, hi, lo_open, hi_open, unit)

    def convert(key, v):
        x = _real(v)
        if x is None or not _inside(x, lo, hi, lo_open, hi_open):
            raise Invalid(key, f"a number in {where}")
        return x
    return Key(convert, f"a number in {where}", also)


def count(lo: int = 1, hi: int = MAX_COUNT, also: str = "") -> Key:
    """An integer in [lo, hi]."""
    def convert(key, v):
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise Invalid(key, f"an integer in [{lo:,}, {hi:,}]")
        return v
    return Key(convert, f"an integer in [{lo:,}, {hi:,}]", also)


def flag(also: str = "") -> Key:
    def convert(key, v):
        if not isinstance(v, bool):
            raise Invalid(key, "true or false")
        return v
    return Key(convert, "true or false", also)


def one_of(*options: str, also: str = "") -> Key:
    text = " or ".join(f'"{o}"' for o in options)

    def convert(key, v):
        if not isinstance(v, str) or v not in options:
            raise Invalid(key, text)
        return v
    return Key(convert, text, also)


def _quantity(to_si: Callable, what: str):
    def read(key, v) -> float:
        try:
            x = to_si(v)
        except UnitError as e:
            raise Invalid(key, str(e)) from None
        if not math.isfinite(x):
            raise Invalid(key, f"a finite {what}")
        return x
    return read


_seconds = _quantity(to_seconds, "time")
_radians = _quantity(to_radians, "angle")


def duration(lo: float = 0.0, hi: float | None = None, *, lo_open: bool = True, hi_open: bool = False,
             also: str = "") -> Key:
    """A time (a bare number in s, or with a unit) in the interval, s."""
    where = _interval(lo, hi, lo_open, hi_open, "s")

    def convert(key, v):
        t = _seconds(key, v)
        if not _inside(t, lo, hi, lo_open, hi_open):
            raise Invalid(key, f"a time in {where}")
        return t
    return Key(convert, f"a time in {where}", also)


def angle_in(lo_deg: float, hi_deg: float, *, lo_open: bool = True, hi_open: bool = False,
             also: str = "") -> Key:
    """An angle (a bare number in rad, or with a unit) in the interval of degrees, rad."""
    where = _interval(lo_deg, hi_deg, lo_open, hi_open, "deg")

    def convert(key, v):
        a = _radians(key, v)
        if not _inside(math.degrees(a), lo_deg, hi_deg, lo_open, hi_open):
            raise Invalid(key, f"an angle in {where}")
        return a
    return Key(convert, f"an angle in {where}", also)


def torque_in(lo: float = 0.0, hi: float | None = None, also: str = "") -> Key:
    """A torque in N.m (a bare number) or with a unit of TORQUE_UNITS, in [lo, hi] N.m."""
    where = _interval(lo, hi, False, False, "N.m")

    def convert(key, v):
        try:
            x, unit = parse_quantity(v)
        except UnitError as e:
            raise Invalid(key, f"a torque in N.m: {e}") from None
        if unit is not None and unit not in TORQUE_UNITS:
            raise Invalid(key, f"a torque unit: one of {', '.join(TORQUE_UNITS)}")
        x *= TORQUE_UNITS.get(unit, 1.0)
        if not math.isfinite(x) or not _inside(x, lo, hi, False, False):
            raise Invalid(key, f"a torque in {where}")
        return x
    return Key(convert, f"a torque in {where}", also)


def durations(lo: float = 0.0, hi: float | None = None, also: str = "") -> Key:
    """A non-empty list of times in (lo, hi], sorted, s; at most MAX_LIST entries."""
    where = _interval(lo, hi, True, False, "s")
    text = f"a list of 1 to {MAX_LIST} times in {where}"

    def convert(key, v):
        if not isinstance(v, list) or not 1 <= len(v) <= MAX_LIST:
            raise Invalid(key, text)
        out = [_seconds(key, x) for x in v]
        if not all(_inside(t, lo, hi, True, False) for t in out):
            raise Invalid(key, text)
        return sorted(out)
    return Key(convert, text, also)


def number_list(lo: float, hi: float, also: str = "") -> Key:
    """A non-empty list of numbers in (lo, hi), sorted; at most MAX_LIST entries."""
    text = f"a list of 1 to {MAX_LIST} numbers in ({lo:g}, {hi:g})"

    def convert(key, v):
        if not (isinstance(v, list) and 1 <= len(v) <= MAX_LIST
                and all(_real(x) is not None and lo < x < hi for x in v)):
            raise Invalid(key, text)
        return sorted(float(x) for x in v)
    return Key(convert, text, also)


def or_word(word: str, key_: Key) -> Key:
    """The literal `word`, or what `key_` accepts."""
    def convert(key, v):
        return word if v == word else key_(key, v)
    return Key(convert, f'"{word}" or {key_.bound}', key_.also)


# The converters of before, each a Key with its bound (kept for the plot
# kinds' keys, which use them too).
positive_number = number(0, None, lo_open=True)
nonnegative_number = number(0, None)
positive_int = count(1, MAX_COUNT)
nonnegative_int = count(0, 2**63 - 1)
boolean = flag()
angle = angle_in(0, 180)
nonnegative_time = duration(0, None, lo_open=False)
torque = torque_in(0)


def time(key: str, v, positive: bool = True) -> float:
    """A time > 0 (or >= 0 when not `positive`), s."""
    return (duration() if positive else nonnegative_time)(key, v)


def choice(key: str, v, options) -> str:
    return one_of(*options)(key, v)


def table_converter(spec: dict):
    """A kind's converter from {key: converter(key, value)}; the spec stays
    on it (``convert.spec``) for the docs and the tests."""
    def convert(t: dict) -> dict:
        return {k: spec[k](k, v) for k, v in t.items()}
    convert.spec = dict(spec)
    return convert


# --- what the scene adds: the FMUs' ranges -----------------------------------------


def within_fmu(scene, key: str, instance: str, variable: str, values, how: str) -> None:
    """Each of `values` (in the variable's unit) within the range
    `instance.variable` declares in its model description, else
    Invalid(key, ...) saying which value `how` gives and the range.
    `how` names the value in words, e.g. "the Air's pressure - delta_hPa"."""
    comp = scene.components[instance]
    v = variables_of(comp.model_description).get(variable)
    if v is None:
        return
    lo, hi = var_limit(v, "min"), var_limit(v, "max")
    unit = f" {var_unit(v)}" if var_unit(v) else ""
    for x in values:
        if (lo is not None and x < lo) or (hi is not None and x > hi) or not math.isfinite(x):
            span = f"[{'-inf' if lo is None else f'{lo:g}'}, {'inf' if hi is None else f'{hi:g}'}]{unit}"
            raise Invalid(key, f"a value that keeps {how} within {comp.model_name}'s range of "
                               f"{instance}.{variable}, {span} (it would be {x:.6g}{unit})")
