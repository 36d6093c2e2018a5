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
        with open(path, encoding="utf-8-sig", newline="") as f:
            return _parse(path, f)
    except (OSError, UnicodeDecodeError) as e:
        raise UsageError(f"{path}: cannot read: {getattr(e, 'strerror', None) or e}") from None


def _parse(path: Path, f) -> tuple[list[str], np.ndarray]:
    lines = ((k, ln) for k, ln in enumerate(f, start=1) if ln.strip() and not ln.lstrip().startswith("#"))
    first = next(lines, None)
    if first is None:
        raise UsageError(f"{path}: expected a header line and at least one row of numbers")
    try:
        delim = csv.Sniffer().sniff(first[1], delimiters=",;\t").delimiter
    except csv.Error:
        delim = ","
    header = [_clean(h) for h in next(csv.reader([first[1]], delimiter=delim))]
    seen: dict[str, int] = {}
    for j, name in enumerate(header):
        if name in seen:
            raise UsageError(f"{path}: line {first[0]}: column {name!r} appears twice (columns {seen[name] + 1} "
                             f"and {j + 1}): expected each signal once")
        seen[name] = j
    values = array("d")
    n_rows = 0
    for k, line in lines:
        cells = next(csv.reader([line], delimiter=delim))
        if len(cells) != len(header):
            raise UsageError(f"{path}: line {k}: {len(cells)} values for {len(header)} columns")
        try:
            values.extend(_number(c) for c in cells)
        except ValueError:
            raise UsageError(f"{path}: line {k}: not a number in {line.strip()[:60]!r}") from None
        n_rows += 1
    if n_rows == 0:
        raise UsageError(f"{path}: expected a header line and at least one row of numbers")
    return header, np.frombuffer(values, dtype=float).reshape(n_rows, len(header))


def _number(cell: str) -> float:
    c = cell.strip().strip('"').lower()
    if c in ("true", "false"):
        return 1.0 if c == "true" else 0.0
    return float(c)


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
        raise UsageError(f"{path}: no such file")
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
