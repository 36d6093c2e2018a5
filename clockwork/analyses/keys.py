"""Converters of analysis-table values, shared by every analysis kind.

Each takes the key (for the message) and the raw TOML value, returns the
value in SI units, and raises ``Invalid(key, expected)`` for a bad one.
Angles take "<n> deg" (or rad), times "<n> s" (or ms, min, ...).
"""

from __future__ import annotations

import math

from ..scene.kinds import Invalid
from ..scene.units import UnitError, parse_quantity, to_radians, to_seconds

TORQUE_UNITS = {"N.m": 1.0, "J": 1.0, "N.cm": 1e-2, "N.mm": 1e-3}


def positive_number(key: str, v) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
        raise Invalid(key, "a positive number")
    return float(v)


def nonnegative_number(key: str, v) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
        raise Invalid(key, "a number >= 0")
    return float(v)


MAX_COUNT = 10_000_000  # a count an analysis takes (periods, samples): each costs steps or memory


def positive_int(key: str, v) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= MAX_COUNT:
        raise Invalid(key, f"a positive integer, at most {MAX_COUNT:,}")
    return v


def nonnegative_int(key: str, v) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or v < 0:
        raise Invalid(key, "an integer >= 0")
    return v


def boolean(key: str, v) -> bool:
    if not isinstance(v, bool):
        raise Invalid(key, "true or false")
    return v


def choice(key: str, v, options) -> str:
    if v not in options:
        raise Invalid(key, " or ".join(f'"{o}"' for o in options))
    return v


def angle(key: str, v, lo: float = 0.0, hi: float = math.pi) -> float:
    """An angle in (lo, hi], rad."""
    try:
        a = to_radians(v)
    except UnitError as e:
        raise Invalid(key, str(e)) from None
    if not lo < a <= hi:
        raise Invalid(key, f"an angle in ({math.degrees(lo):g}, {math.degrees(hi):g}] deg")
    return a


def time(key: str, v, positive: bool = True) -> float:
    """A time > 0 (or >= 0 when not `positive`), s."""
    try:
        t = to_seconds(v)
    except UnitError as e:
        raise Invalid(key, str(e)) from None
    if positive and not t > 0:
        raise Invalid(key, "a positive time")
    if not positive and not t >= 0:
        raise Invalid(key, "a time >= 0")
    return t


def nonnegative_time(key: str, v) -> float:
    return time(key, v, positive=False)


def times(key: str, v) -> list[float]:
    """A non-empty list of positive times, sorted, s."""
    if not isinstance(v, list) or not v:
        raise Invalid(key, "a non-empty list of times")
    return sorted(time(key, x) for x in v)


def numbers(key: str, v, lo: float = 0.0, hi: float = math.inf) -> list[float]:
    """A non-empty list of numbers in (lo, hi), sorted."""
    if not (isinstance(v, list) and v and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                             and lo < x < hi for x in v)):
        raise Invalid(key, f"a non-empty list of numbers in ({lo:g}, {hi:g})")
    return sorted(float(x) for x in v)


def torque(key: str, v) -> float:
    """A torque >= 0 in N.m (a bare number) or with a unit of TORQUE_UNITS."""
    try:
        x, unit = parse_quantity(v)
    except UnitError as e:
        raise Invalid(key, f"a torque in N.m: {e}") from None
    if unit is not None and unit not in TORQUE_UNITS:
        raise Invalid(key, f"a torque unit: one of {', '.join(TORQUE_UNITS)}")
    x *= TORQUE_UNITS.get(unit, 1.0)
    if not x >= 0:
        raise Invalid(key, "a torque >= 0")
    return x


def table_converter(spec: dict):
    """A kind's converter from {key: converter(key, value)}."""
    def convert(t: dict) -> dict:
        return {k: spec[k](k, v) for k, v in t.items()}
    return convert
