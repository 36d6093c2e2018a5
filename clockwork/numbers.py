"""Numbers read from text: one strict reader for every format clockwork reads.

Python's ``float()`` accepts what neither XML Schema's ``xs:double`` nor
CSV nor JSON has: underscores between digits (``"1_0"`` is 10),
surrounding blanks, ``"infinity"`` and ``"nan"`` in any case, and full-width
digits. A file that another tool would refuse must not be read here as some
other number, so every number that comes from a file goes through
``parse_real`` (or ``parse_int``), and ``float()`` stays for numbers that
clockwork computed itself.
"""

from __future__ import annotations

import json
import math
import re

# A decimal number with an optional sign, fraction and exponent: the lexical
# space of xs:double and xs:decimal (without INF/NaN), of JSON numbers (plus
# a leading "+" and a bare ".5" or "5.", which xs:double allows), and of the
# numbers every CSV writer in use prints.
_DECIMAL = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_INTEGER = re.compile(r"[+-]?[0-9]+")

# xs:double's special values, spelled exactly as XML Schema spells them.
XSD_SPECIAL = {"INF": math.inf, "+INF": math.inf, "-INF": -math.inf, "NaN": math.nan}

# The spellings of non-finite values that CSV writers in use print (numpy,
# pandas, fmpy, libcosim, OMSimulator): compared case-insensitively.
CSV_SPECIAL = {"nan": math.nan, "inf": math.inf, "+inf": math.inf, "-inf": -math.inf,
               "infinity": math.inf, "+infinity": math.inf, "-infinity": -math.inf}


def parse_real(text: str, special: dict[str, float] | None = None,
               special_case_insensitive: bool = False) -> float:
    """The number `text` spells, else ValueError.

    `special`: the spellings of non-finite values this format has (e.g.
    ``XSD_SPECIAL``); without it INF and NaN are refused too. No blanks,
    no underscores, no other Unicode digits.
    """
    if not isinstance(text, str):
        raise ValueError(f"expected text, got {type(text).__name__}")
    if _DECIMAL.fullmatch(text):
        return float(text)
    if special:
        key = text.lower() if special_case_insensitive else text
        if key in special:
            return special[key]
    raise ValueError(f"not a number: {shorten(text, 60)!r}")


def parse_int(text: str) -> int:
    """The integer `text` spells (decimal digits with an optional sign), else ValueError."""
    if not isinstance(text, str):
        raise ValueError(f"expected text, got {type(text).__name__}")
    if _INTEGER.fullmatch(text):
        return int(text)
    raise ValueError(f"not an integer: {shorten(text, 60)!r}")


def shorten(text: object, limit: int = 200) -> str:
    """`text` as a string of at most about `limit` characters: a value echoed
    in an error line (an attribute, a CSV field) must not flood the terminal."""
    s = str(text)
    if len(s) <= limit:
        return s
    keep = max(limit - 30, 10)
    return f"{s[:keep]}... ({len(s)} characters)"


def parse_json(text: str | bytes):
    """The JSON value `text` holds, read as RFC 8259 has it, else ValueError.

    Python's ``json.loads`` also accepts ``NaN``, ``Infinity`` and
    ``-Infinity``, numbers that overflow a double (``1e400`` reads as
    infinity) and an object that names a key twice (the last one wins);
    each is refused here, so that no file read by clockwork holds a number
    that no strict reader would see, or a value that silently replaced
    another.
    """
    return json.loads(text, parse_constant=_no_constant, parse_float=_finite_float,
                      object_pairs_hook=_unique_keys)


def _no_constant(name: str):
    raise ValueError(f"{name} is not JSON (JSON has no NaN or infinity)")


def _finite_float(text: str) -> float:
    x = float(text)
    if not math.isfinite(x):
        raise ValueError(f"the number {shorten(text, 60)} is beyond the range of a double")
    return x


def _unique_keys(pairs: list) -> dict:
    out = {}
    for key, value in pairs:
        if key in out:
            raise ValueError(f"the key {shorten(key, 60)!r} is given twice in one object")
        out[key] = value
    return out
