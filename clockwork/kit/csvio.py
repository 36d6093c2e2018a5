"""Result CSV files as the co-simulation tools write them, read into one table.

Accepted layouts (one time column, then signals):

- fmpy (``fmpy.util.write_csv``, ``simulate_ssp``): ``time`` and the
  variable names (``phi``) or connector paths (``pendulum.phi``);
- OMSimulator: ``time`` and ``model.root.pendulum.phi`` style names;
- libcosim: a single file ``Time``/``<slave>.<var>``, or the directory its
  file observer writes (one ``<slave>_<date>.csv`` per slave with
  ``Time``, ``StepCount`` and ``<var> [<ref> <type> <causality>]`` columns);
- ecos: ``time`` and ``<instance>::<var>`` (``::`` is read as ``.``); its CSV
  writer's ``iterations, time, <inst>::<var>[REAL]`` too.

Names are matched to a case's signals by suffix at a dot: the signal
``pendulum.phi`` matches ``pendulum.phi``, ``model.root.pendulum.phi``
and ``pendulum::phi``; ``phi`` (a single-FMU case) matches any column
whose last part is ``phi`` when exactly one does.
"""

from __future__ import annotations

import csv
import io
import math
import re
from array import array
from pathlib import Path

import numpy as np

from ..atomic import write_text_atomic
from ..errors import UsageError
from ..files import absent, open_regular
from ..numbers import CSV_SPECIAL, parse_real, shorten

_TIME = ("time", "t")
_COUNTERS = ("stepcount", "iterations", "step")
_BRACKET = re.compile(r"\s*\[[^\]]*\]\s*$")  # libcosim's " [0 Real OUT]"


def write_csv(path: str | Path, names: list[str], data: np.ndarray) -> Path:
    """A CSV with a header line and full-precision values (no NaN)."""
    buf = io.StringIO()
    buf.write(",".join(names) + "\n")
    for row in np.asarray(data, dtype=float):
        buf.write(",".join(repr(float(x)) for x in row) + "\n")
    return write_text_atomic(path, buf.getvalue())


def _clean(name: str) -> str:
    name = _BRACKET.sub("", name.strip().strip('"').strip())
    return name.replace("::", ".")


def _read_table(path: Path) -> tuple[list[str], np.ndarray]:
    """Header and rows of numbers, read as a stream: memory holds the numbers
    (8 bytes each) and one line at a time, never the text. A UTF-8 byte order
    mark (Excel writes one) is skipped; a column name given twice is refused."""
    try:
        with io.TextIOWrapper(open_regular(path, "a result CSV file"), encoding="utf-8-sig", newline="") as f:
            return _parse(path, f)
    except (OSError, UnicodeDecodeError) as e:
        raise UsageError(f"{path}: cannot read: {getattr(e, 'strerror', None) or e}") from None


# A line of a result CSV: far more than a row of numbers needs (40,000
# columns of 25 characters), and a bound on what one line costs in memory.
MAX_LINE = 1 << 20


def _numbered_lines(path: Path, f):
    """(line number, text) of the lines that are neither blank nor comments,
    each read up to MAX_LINE characters."""
    k = 0
    while True:
        line = f.readline(MAX_LINE + 1)
        if not line:
            return
        k += 1
        if len(line) > MAX_LINE:
            raise UsageError(f"{path}: line {k}: longer than {MAX_LINE:,} characters: expected a header line and "
                             "rows of numbers")
        if line.strip() and not line.lstrip().startswith("#"):
            yield k, line


def _cells(path: Path, k: int, line: str, delim: str) -> list[str]:
    """The fields of one line; the csv module's own complaints (a field over
    its limit of 131,072 characters, a NUL byte) as one line naming it."""
    try:
        return next(csv.reader([line], delimiter=delim), [])
    except csv.Error as e:
        raise UsageError(f"{path}: line {k}: not a CSV line of numbers ({e})") from None


def _parse(path: Path, f) -> tuple[list[str], np.ndarray]:
    lines = _numbered_lines(path, f)
    first = next(lines, None)
    if first is None:
        raise UsageError(f"{path}: expected a header line and at least one row of numbers")
    try:
        delim = csv.Sniffer().sniff(first[1][:4096], delimiters=",;\t").delimiter
    except csv.Error:
        delim = ","
    header = [_clean(h) for h in _cells(path, first[0], first[1], delim)]
    seen: dict[str, int] = {}
    for j, name in enumerate(header):
        if name in seen:
            raise UsageError(f"{path}: line {first[0]}: column {shorten(name, 80)!r} appears twice (columns "
                             f"{seen[name] + 1} and {j + 1}): expected each signal once")
        seen[name] = j
    values = array("d")
    n_rows = 0
    plain = _plain_row(delim)
    for k, line in lines:
        if plain.fullmatch(line):  # the common row: decimal numbers only, checked by one regex
            cells = line.split(delim)
            if len(cells) == len(header):
                values.extend(map(float, cells))  # what float() reads beyond the regex cannot be here
                n_rows += 1
                continue
        else:
            cells = _cells(path, k, line, delim)
        if len(cells) != len(header):
            raise UsageError(f"{path}: line {k}: {len(cells)} values for {len(header)} columns")
        try:
            values.extend(map(_number, cells))
        except ValueError:
            j = next(j for j, c in enumerate(cells) if not _is_number(c))
            raise UsageError(f"{path}: line {k}: not a number in column {j + 1} ({shorten(header[j], 80)}): "
                             f"{shorten(cells[j], 60)!r}: expected a decimal number within a double's range, "
                             "nan, inf or true/false") from None
        n_rows += 1
    if n_rows == 0:
        raise UsageError(f"{path}: expected a header line and at least one row of numbers")
    return header, np.frombuffer(values, dtype=float).reshape(n_rows, len(header))


def _plain_row(delim: str) -> re.Pattern:
    """A line of decimal numbers (clockwork.numbers' syntax) between `delim`,
    blanks around each allowed, ending in a newline or not; at most 30
    digits before and after the point and a two-digit exponent, so that none
    overflows a double (the rest take the slow path, _number)."""
    number = r"[ \t]*[+-]?(?:[0-9]{1,30}(?:\.[0-9]{0,30})?|\.[0-9]{1,30})(?:[eE][+-]?[0-9]{1,2})?[ \t]*"
    return re.compile(f"{number}(?:{re.escape(delim)}{number})*\r?\n?")


_BLANKS = " \t\r\n"  # what CSV writers put around a field (not Unicode's other spaces)


def _number(cell: str) -> float:
    """A field as a number: a decimal number as CSV writers print it
    (clockwork.numbers, no "1_0"), nan and inf in any case, true/false;
    blanks and quotes around it are the CSV's, not the number's."""
    c = cell.strip(_BLANKS).strip('"').strip(_BLANKS)
    low = c.lower()
    if low in ("true", "false"):
        return 1.0 if low == "true" else 0.0
    x = parse_real(c, CSV_SPECIAL, special_case_insensitive=True)
    if math.isinf(x) and low not in CSV_SPECIAL:
        raise ValueError(f"{c} is beyond the range of a double")
    return x


def _is_number(cell: str) -> bool:
    try:
        _number(cell)
    except ValueError:
        return False
    return True


class Result:
    """A tool's result: time (s) and {column name: values}."""

    def __init__(self, source: str, time: np.ndarray, columns: dict[str, np.ndarray]):
        self.source = source
        self.time = time
        self.columns = columns

    def match(self, signal: str) -> str | None:
        """The column that is `signal` (suffix at a dot), or None."""
        hits = [c for c in self.columns if c == signal or c.endswith("." + signal)]
        if len(hits) > 1:
            raise UsageError(f"{self.source}: columns {hits[0]!r} and {hits[1]!r} are both the signal {signal!r}: "
                             "expected each signal once")
        return hits[0] if hits else None


def read_result(path: str | Path) -> Result:
    """A result CSV, or a libcosim directory of per-slave CSVs."""
    path = Path(path)
    if path.is_dir():
        return _read_slave_dir(path)
    if not path.is_file():
        raise UsageError(f"{path}: {absent(path, 'a result CSV file')}")
    header, data = _read_table(path)
    return _result(str(path), header, data, path)


def _result(source: str, header: list[str], data: np.ndarray, path: Path) -> Result:
    # The time is the first column, after a counter (ecos: iterations, time, ...).
    lead = [j for j, h in enumerate(header) if h.lower() in _TIME]
    if not lead or any(header[j].lower() not in _COUNTERS for j in range(lead[0])):
        raise UsageError(f"{path}: the first column must be the time ('time' or 'Time'), got {header[0]!r}")
    if data.shape[0] < 2:
        raise UsageError(f"{path}: at least two rows are needed")
    jt = lead[0]
    t = data[:, jt]
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0):
        raise UsageError(f"{path}: the time column must be finite and non-decreasing")
    cols = {}
    for j, name in enumerate(header):
        if j == jt or name.lower() in _COUNTERS:
            continue
        cols[name] = data[:, j]
    return Result(source, t, cols)


def _read_slave_dir(d: Path) -> Result:
    files = sorted(d.glob("*.csv"))
    if not files:
        raise UsageError(f"{d}: a directory without .csv files")
    time = None
    cols: dict[str, np.ndarray] = {}
    for f in files:
        header, data = _read_table(f)
        r = _result(str(f), header, data, f)
        # libcosim names the file <slave>_<yyyymmdd>_<hhmmss>_<...>.csv
        slave = re.sub(r"(_\d{8}_\d{6}.*|_\d+)?$", "", f.stem, count=1) or f.stem
        if time is None:
            time = r.time
        elif len(r.time) != len(time) or np.max(np.abs(r.time - time)) > 1e-9 * max(1.0, abs(time[-1])):
            raise UsageError(f"{f}: its time column differs from {files[0].name}'s")
        for name, v in r.columns.items():
            full = name if "." in name else f"{slave}.{name}"
            if full in cols:
                raise UsageError(f"{f}: column {full!r} is also in another file of {d.name}: "
                                 "expected each signal once")
            cols[full] = v
    return Result(str(d), time, cols)


def finite(values: np.ndarray) -> bool:
    return bool(np.all(np.isfinite(values)))


def fmt_float(x: float) -> str:
    if x is None or not math.isfinite(x):
        return "-"
    return f"{x:.3g}"
