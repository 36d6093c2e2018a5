"""Input files: samples that drive unconnected inputs (docs/scenes.md, "Inputs").

An input file is a CSV file: a header line whose first column is ``time``
and whose other columns name inputs (``instance.variable``; the variable
alone where the scene has one component, as fmpy's input files name
them), then one row of numbers per sample time, comma-separated. Times
never decrease; a time given twice is a step. Real inputs take decimal
numbers in the variable's own unit (finite, within its min and max),
integer and Enumeration inputs integers, Boolean inputs ``true``/``false``
or ``1``/``0``. Blank lines and lines starting with ``#`` are skipped.
How the values are used between samples is the engine's
(``engine.samples``: fmpy's rules).

A scene names its file in ``[inputs] file = "..."`` (relative to the
scene file); ``clockwork run --input FILE`` gives one for any scene, SSP
or FMU. Every problem is one ``SceneError`` line naming the file, the line
and the column.
"""

from __future__ import annotations

import csv
import difflib
import hashlib
import math
import os
from array import array
from dataclasses import dataclass
from pathlib import Path

from ..fmi.description import FLOAT32_MAX, INTEGER_TYPES, TEXT_TYPES, element_names, int_range, var_limit
from ..fmi.description import variables as variables_of
from ..engine.names import split_ref
from ..engine.samples import Samples, Signal, is_continuous
from ..errors import SceneError
from ..files import NotRegularFile, open_regular
from ..numbers import parse_int, parse_real, shorten
from .units import fmt

# An input file's bytes. Its samples are kept as 8-byte numbers (a cell "0,"
# is 2 bytes: 4 bytes of memory a byte of file), Booleans as pointers to
# True and False (8 bytes, and as much again while the column becomes a
# tuple): at most about 1.1 GB for 128 MiB; a file of Real samples written
# with all their digits (about 20 bytes a cell) takes far less
# (docs/reliability.md, "Bounds known before the work starts").
MAX_INPUT_BYTES = 1 << 27
MAX_LINE = 1 << 22  # bytes of one line: 100,000 columns of 40 characters
REAL_TYPES = ("Real", "Float32", "Float64")


@dataclass(frozen=True)
class Inputs:
    """The samples a scene drives its inputs with, and where they come from."""

    file: Path | None  # the CSV file; None for samples given in Python
    sha256: str  # of the file's bytes (of the samples' values when given in Python)
    samples: Samples

    @property
    def columns(self) -> list[str]:
        return [s.name for s in self.samples.signals]


class _Fail:
    """Errors of one source: `fail(line, column, detail)` -> SceneError."""

    def __init__(self, path: Path | str, names: list[str]):
        self.path = path
        self.names = names

    def __call__(self, line: int | None, column: int | None, detail: str) -> SceneError:
        where = []
        if line is not None:
            where.append(f"line {line}")
        if column is not None:
            where.append(f"column {column + 1} ({shorten(self.names[column], 60)})"
                         if column < len(self.names) else f"column {column + 1}")
        return SceneError(detail, self.path, ", ".join(where) or None)


def targets(names: list[str], components: dict, connected: set, parameters: set, fail, line=None) -> list:
    """The input variable each column (after the first, time) names:
    [(instance, variable name, ScalarVariable)]; an unknown, connected or
    non-input column is refused, naming it."""
    variables = {n: variables_of(c.model_description) for n, c in components.items()}
    only = next(iter(components)) if len(components) == 1 else None
    seen: dict[tuple[str, str], int] = {}
    out = []
    for j, name in enumerate(names):
        if j == 0:
            continue
        split = split_ref(name, variables)
        if (split is None or split[1] not in variables[split[0]]) and only is not None and name in variables[only]:
            split = (only, name)
        if split is None or split[1] not in variables[split[0]]:
            free = [f"{i}.{v}" if only is None else v for i, vs in variables.items() for v, var in vs.items()
                    if var.causality == "input" and (i, v) not in connected]
            close = difflib.get_close_matches(name, free, n=1)
            hint = f" (did you mean {close[0]}?)" if close else ""
            raise fail(line, j, f"no input of that name{hint}; expected one of the unconnected inputs: "
                                f"{shorten(', '.join(free), 300) or 'none'}")
        inst, var = split
        v = variables[inst][var]
        if v.causality != "input":
            raise fail(line, j, f"{inst}.{var} is a {v.causality}, not an input (an input file drives inputs; "
                                f"a parameter is set with --set {inst}.{var}=...)")
        if (inst, var) in connected:
            raise fail(line, j, f"{inst}.{var} is connected: an input is either connected or driven from a file")
        if (inst, var) in parameters:
            raise fail(line, j, f"{inst}.{var} is also given a value in the scene (components.{inst}.parameters, "
                                "a parameter binding or --set): expected it in one place")
        if v.type in TEXT_TYPES:
            raise fail(line, j, f"{inst}.{var} is a {v.type}: an input file drives numbers and Booleans")
        if getattr(v, "shape", None):  # an FMI 3.0 array: one number per column cannot fill it
            elements = element_names(v)
            shown = ", ".join(f"{inst}.{e}" if only is None else e for e in elements[:3])
            raise fail(line, j, f"{inst}.{var} is an array of {len(elements)} values: expected a column per element"
                                f" ({shown}{', ...' if len(elements) > 3 else ''})" if elements else
                       f"{inst}.{var} is an empty array: no value to drive")
        if (inst, var) in seen:
            raise fail(line, j, f"{inst}.{var} is also column {seen[(inst, var)] + 1}: expected each input once")
        seen[(inst, var)] = j
        out.append((inst, var, v))
    _whole_arrays(out, variables, names, seen, fail, line)
    return out


def _whole_arrays(out: list, variables: dict, names: list[str], seen: dict, fail, line) -> None:
    """Columns for elements of an FMI 3.0 array ("u[1]") drive it only
    when every element has one: the FMU takes an array whole (fmi3Set*
    of part of one is an error at the run), so a missing element is
    refused here, where validate sees it too."""
    given: dict[tuple[str, int], list] = {}
    for inst, var, v in out:
        array = getattr(v, "array", None)
        if array is not None:
            given.setdefault((inst, id(array)), [array, set(), seen[(inst, var)]])[1].add(getattr(v, "index", 0))
    for (inst, _), (array, indices, j) in given.items():
        size = math.prod(array.shape)
        if len(indices) < size:
            missing = min(set(range(size)) - indices)
            name = next((n for n, x in variables[inst].items()
                         if getattr(x, "array", None) is array and getattr(x, "index", 0) == missing), str(missing))
            raise fail(line, j, f"{inst}.{array.name} is an array of {size} values set whole: expected a column "
                                f"for each element, {inst}.{name} is missing ({len(indices)} of {size} given)")


def sample_value(x, v):
    """A sample of input `v`, from text or a number, checked; ValueError says what was expected."""
    kind = v.type
    if kind == "Boolean":
        if isinstance(x, str):
            s = x.lower()
            if s in ("true", "1"):
                return True
            if s in ("false", "0"):
                return False
            raise ValueError("expected true, false, 1 or 0 (a Boolean input)")
        if x in (0, 1):
            return bool(x)
        raise ValueError("expected true, false, 1 or 0 (a Boolean input)")
    if kind in INTEGER_TYPES:
        try:
            n = parse_int(x) if isinstance(x, str) else int(x)
            if not isinstance(x, str) and n != x:
                raise ValueError
        except (ValueError, OverflowError, TypeError):
            raise ValueError(f"expected an integer ({kind} input)") from None
        bounds = int_range(kind)
        if bounds and not bounds[0] <= n <= bounds[1]:
            raise ValueError(f"expected an integer in [{bounds[0]}, {bounds[1]}] ({kind})")
        items = {int(i.value) for i in getattr(v.declaredType, "items", None) or []}
        if kind == "Enumeration" and items and n not in items:
            raise ValueError(f"expected the value of an item of {v.declaredType.name}: "
                             f"{', '.join(map(str, sorted(items)))}")
        value = n
    else:
        try:
            value = parse_real(x) if isinstance(x, str) else float(x)
        except (ValueError, TypeError):
            raise ValueError("expected a decimal number (a Real input)") from None
        if value != value or value in (float("inf"), float("-inf")):
            raise ValueError("expected a finite number (a Real input)")
        if kind == "Float32" and not abs(value) <= FLOAT32_MAX:
            raise ValueError(f"expected a Float32 value, in [-{FLOAT32_MAX:g}, {FLOAT32_MAX:g}]")
    lo, hi = var_limit(v, "min"), var_limit(v, "max")
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        raise ValueError(f"expected a value in [{fmt(lo) if lo is not None else '-inf'}, "
                         f"{fmt(hi) if hi is not None else 'inf'}] (the input's min and max)")
    return value


def make_samples(times, columns: list, bound: list) -> Samples:
    """Samples of the checked columns (Real ones as arrays of doubles)."""
    signals = []
    for (inst, var, v), values in zip(bound, columns):
        if v.type in REAL_TYPES:
            kept = values if isinstance(values, array) and values.typecode == "d" else array("d", values)
        else:
            kept = values if isinstance(values, array) else tuple(values)
        signals.append(Signal(inst, var, kept, is_continuous(v)))
    return Samples(times, _elements_in_order(signals, bound))


def _elements_in_order(signals: list, bound: list) -> list:
    """The signals with the elements of each FMI 3.0 array side by side in
    the array's order (u[1], x, u[0] -> u[0], u[1], x): the FMU takes an
    array in one fmi3Set* call of its elements in order, whatever order the
    columns came in. Other signals keep their place."""
    first: dict[tuple[str, int], int] = {}
    keys = []
    for k, (inst, _, v) in enumerate(bound):
        array = getattr(v, "array", None)
        if array is None:
            keys.append((k, 0))
        else:
            keys.append((first.setdefault((inst, id(array)), k), getattr(v, "index", 0)))
    return [s for _, s in sorted(zip(keys, signals), key=lambda p: p[0])]


def read_inputs(path: Path, components: dict, connected: set = frozenset(), parameters: set = frozenset()) -> Inputs:
    """An input file, read and checked against the scene's components: read
    as a stream, a line at a time, into arrays of doubles (memory holds the
    numbers, not the text: docs/reliability.md)."""
    path = Path(path)
    try:
        f = open_regular(path, "a CSV input file")
    except NotRegularFile as e:
        raise SceneError(e.detail, path) from None
    except FileNotFoundError:
        raise SceneError("no such input file", path) from None
    except OSError as e:
        raise SceneError(f"cannot read: {e.strerror}", path) from None
    with f:
        size = os.fstat(f.fileno()).st_size
        if size > MAX_INPUT_BYTES:
            raise SceneError(f"{size} bytes: an input file is at most {MAX_INPUT_BYTES} bytes", path)
        digest = hashlib.sha256()
        try:
            return _parse(path, _lines(path, f, digest), digest, components, connected, parameters)
        except OSError as e:
            raise SceneError(f"cannot read: {e.strerror}", path) from None


def _lines(path: Path, f, digest):
    """(line number, text) of the lines that are neither blank nor comments,
    each at most MAX_LINE bytes; every byte read goes into `digest`."""
    k = offset = 0
    while True:
        raw = f.readline(MAX_LINE + 1)
        if not raw:
            return
        digest.update(raw)
        k += 1
        if len(raw) > MAX_LINE:
            raise SceneError(f"longer than {MAX_LINE:,} bytes: expected a CSV input file", path, f"line {k}")
        start = 3 if k == 1 and raw.startswith(b"\xef\xbb\xbf") else 0  # a byte order mark (Excel writes one)
        try:
            line = raw[start:].decode("utf-8")
        except UnicodeDecodeError as e:
            raise SceneError(f"not UTF-8 text (byte {offset + start + e.start})", path) from None
        offset += len(raw)
        if line.strip() and not line.lstrip().startswith("#"):
            yield k, line.rstrip("\n")


def _parse(path: Path, lines, digest, components: dict, connected: set, parameters: set) -> Inputs:
    first = next(lines, None)
    if first is None:
        raise SceneError("empty: expected a header line (time, then inputs) and rows of samples", path)
    header_line, header_text = first
    names = [n.strip() for n in _cells(header_text.rstrip("\r"), path, header_line)]
    fail = _Fail(path, names)
    if names[0].lower() != "time":
        hint = " (comma-separated values are expected)" if len(names) == 1 and (";" in names[0] or "\t" in names[0]) \
            else ""
        raise fail(header_line, 0, f"expected the first column to be time{hint}")
    for j, n in enumerate(names):
        if not n:
            raise fail(header_line, j, "an empty column name: expected time, then input names")
    bound = targets(names, components, connected, parameters, fail, header_line)
    times: array = array("d")
    # Real columns straight into arrays of doubles: 8 bytes a number, not a float object's 32.
    columns = [_column(v.type) for _, _, v in bound]
    for k, raw in lines:
        cells = _cells(raw.rstrip("\r"), path, k)
        if len(cells) != len(names):
            raise fail(k, None, f"{len(cells)} values for {len(names)} columns")
        cell = cells[0].strip()
        try:
            t = parse_real(cell)
        except ValueError:
            raise fail(k, 0, f"expected a time in s (a decimal number), got {shorten(cell, 40)!r}") from None
        if t != t or t in (float("inf"), float("-inf")):
            raise fail(k, 0, "expected a finite time in s")
        if times and t < times[-1]:
            raise fail(k, 0, f"{fmt(t)} s is before the time of the row above ({fmt(times[-1])} s): expected times "
                             "that never decrease (a time given twice is a step)")
        times.append(t)
        for j, (column, (inst, var, v)) in enumerate(zip(columns, bound), start=1):
            cell = cells[j].strip()
            try:
                column.append(sample_value(cell, v))
            except ValueError as e:
                raise fail(k, j, f"{e}, got {shorten(cell, 40)!r}") from None
    if not times:
        raise SceneError("no samples: expected rows of numbers after the header line", path)
    return Inputs(path, digest.hexdigest(), make_samples(times, columns, bound))


def _column(kind: str):
    """An empty column for samples of an input of this type: an array of
    doubles or of 64-bit integers where the type fits one (8 bytes a sample),
    else a list (Booleans: True and False are shared objects)."""
    if kind in REAL_TYPES:
        return array("d")
    if kind in INTEGER_TYPES:
        return array("Q" if kind == "UInt64" else "q")
    return []


def _cells(line: str, path: Path, k: int) -> list[str]:
    try:
        return next(csv.reader([line], strict=True))
    except csv.Error as e:
        raise SceneError(f"malformed CSV: {e}", path, f"line {k}") from None
