"""``clockwork.load(DIR)``: a finished run's directory as one object.

A run (``clockwork run ... --out DIR``) leaves summary.json, its data
(timeseries.csv, or .parquet or .mat, for a run; sweep.csv for a sweep)
and its plots (PNG files that summary.json names). `load` checks that DIR
is such a directory (summary.json read with `clockwork plot`'s checks,
``plots.redraw``, and its ``tool`` must be clockwork) and hands back a
`Result`: the summary at once, the data read on first use from whichever
file is there (Parquet through pyarrow where installed, then CSV, then
the MAT file in the Modelica result layout through SciPy), the plots as
paths. In Jupyter it shows itself (the summary as a table, the plots
inline); `plot` draws chosen columns; `to_pandas` gives a DataFrame.

Everything read is checked: a directory of another program, a missing
or unreadable file, a file of the wrong shape is one `UsageError` naming
the path and what was expected.
"""

from __future__ import annotations

import base64
import csv
import fnmatch
import html
import math
from pathlib import Path

import numpy as np

from ..arguments import Path as PathSpec
from ..arguments import checked, fspath
from ..errors import UsageError, printable
from ..files import absent, open_regular
from ..numbers import CSV_SPECIAL, parse_real, shorten
from .plots.redraw import _summary as read_summary

EXPECTED = "the --out directory of a clockwork run"
SERIES_FILES = ("timeseries.parquet", "timeseries.csv", "timeseries.mat")  # the order they are tried in
MAX_INLINE_PLOTS = 12  # images a notebook shows inline; the others are listed by name
MAX_INLINE_BYTES = 8 << 20  # a PNG larger than this is listed, not embedded
MAX_TABLE_ROWS = 20  # rows of a sweep's table shown in a notebook

# FMI types (summary.json's columns[...].type) -> the dtype clockwork.simulate gives them.
_DTYPES = {"Integer": np.int32, "Int32": np.int32, "Int8": np.int8, "UInt8": np.uint8, "Int16": np.int16,
           "UInt16": np.uint16, "UInt32": np.uint32, "Int64": np.int64, "UInt64": np.uint64,
           "Enumeration": np.int64, "Boolean": np.bool_, "Float32": np.float32}
_TEXT = ("String", "Binary")


@checked(path=PathSpec(f"a path (a string or pathlib.Path): {EXPECTED}"))
def load(path) -> "Result":
    """The finished run in directory `path` (a `clockwork run --out`
    directory, or `clockwork.run`'s): a `Result` with its summary, its
    data (read on first use) and its plots. Raises UsageError, naming the
    path, for anything that is not such a directory."""
    folder = Path(fspath(path))
    if not folder.is_dir():
        raise UsageError(f"{folder}: {absent(folder, EXPECTED, 'no such directory: expected ' + EXPECTED)}")
    summary = read_summary(folder)  # `clockwork plot`'s checks: size, strict JSON, shape of what is drawn
    where = folder / "summary.json"
    tool = summary.get("tool")
    if not (isinstance(tool, dict) and tool.get("name") == "clockwork"):
        raise UsageError(f"{where}: tool: expected {{\"name\": \"clockwork\", ...}}: not a summary clockwork wrote "
                         f"(is {folder} {EXPECTED}?)")
    for key, kind, what in (("files", list, "a list of file names"), ("points", list, "a list"),
                            ("result", dict, "an object"), ("statistics", dict, "an object"),
                            ("headlines", list, "a list"), ("settings", dict, "an object")):
        if key in summary and not isinstance(summary[key], kind):
            raise UsageError(f"{where}: {key}: expected {what}")
    files = summary.get("files", [])
    for i, name in enumerate(files):
        if not isinstance(name, str) or not _plain_name(name):
            raise UsageError(f"{where}: files[{i}] = {shorten(repr(name), 80)}: expected the name of a file in "
                             f"{folder} (no directory, not hidden)")
    return Result(folder, summary)


def _plain_name(name: str) -> bool:
    return bool(name) and "/" not in name and "\\" not in name and not name.startswith(".") and "\x00" not in name


class Result:
    """A finished run: `path`, `summary` (summary.json as a dict), `plots`
    (the PNG files it lists, as paths), `series` (a run's time series as a
    NumPy structured array, `time` first, as `clockwork.simulate` returns
    it), `table` (a sweep's sweep.csv, one row per point), `plot(...)`
    and `to_pandas()`. The data are read on first use, then kept."""

    def __init__(self, path: Path, summary: dict):
        self.path = path
        self.summary = summary
        self._series: np.ndarray | None = None
        self._table: np.ndarray | None = None

    # -- what it is -------------------------------------------------------------

    @property
    def title(self) -> str:
        return self.summary.get("title") or self.path.name

    @property
    def is_sweep(self) -> bool:
        """True for a sweep (a table of points), False for a single run (a time series)."""
        return "points" in self.summary or (self.path / "sweep.csv").is_file()

    @property
    def failed(self) -> str | None:
        """Why the run failed (its data are the history until then), or None."""
        result = self.summary.get("result")
        failed = result.get("failed") if isinstance(result, dict) else None
        return printable(failed if isinstance(failed, str) else self.summary.get("error")) if (
            failed or self.summary.get("error")) else None

    @property
    def files(self) -> list[str]:
        return list(self.summary.get("files", []))

    @property
    def plots(self) -> list[Path]:
        """The PNG files the run wrote that are there, in its order."""
        return [self.path / n for n in self.files if n.lower().endswith(".png") and (self.path / n).is_file()]

    @property
    def series_file(self) -> Path | None:
        """The file `series` reads: timeseries.parquet (when pyarrow is installed), .csv or .mat; None without."""
        for name in SERIES_FILES:
            p = self.path / name
            if p.is_file() and (name != "timeseries.parquet" or _has("pyarrow")):
                return p
        parquet = self.path / "timeseries.parquet"
        if parquet.is_file():  # the only one, and pyarrow missing: say how to read it
            raise UsageError(f"{parquet}: reading Parquet needs pyarrow: pip install 'clockwork-fmi[parquet]' "
                             "(or pip install pyarrow)")
        return None

    @property
    def columns(self) -> list[str]:
        """The names of the data's columns (of `series`, or of `table` for a sweep)."""
        return list((self.table if self.is_sweep else self.series).dtype.names)

    # -- the data ----------------------------------------------------------------

    @property
    def series(self) -> np.ndarray:
        """The time series: a structured array, `time` (s) first, then a
        field per recorded variable, named as `clockwork.simulate` names them
        (the variable alone for one FMU, ``instance.variable`` for a
        system), typed by the variable's FMI type."""
        if self._series is None:
            if self.is_sweep and not self._has_series_file():
                raise UsageError(f"{self.path}: a sweep of {len(self.summary.get('points', []))} points: it keeps no "
                                 "time series; .table holds a row per point")
            source = self.series_file
            if source is None:
                raise UsageError(f"{self.path}: no timeseries.csv, .parquet or .mat: the run recorded no time series "
                                 "(an analysis that keeps none)")
            columns = _read_series(source, self.summary.get("columns", {}))
            self._series = _structured(columns, self.summary.get("columns", {}), self._strip(), source)
        return self._series

    @property
    def table(self) -> np.ndarray:
        """A sweep's points: sweep.csv as a structured array (the sweep's
        axes, then the result columns; a column of text stays text)."""
        if self._table is None:
            source = self.path / "sweep.csv"
            if not self.is_sweep or not source.is_file():
                raise UsageError(f"{self.path}: no sweep.csv: not a sweep (its time series is .series)")
            header, cells = _read_csv(source)
            fields, data = [], []
            for name, col in zip(header, cells):
                numbers = _numbers(col)
                if numbers is None:
                    fields.append((name, object))
                    data.append(np.asarray([c if c else None for c in col], dtype=object))
                else:
                    fields.append((name, np.float64))
                    data.append(numbers)
            self._table = _pack(fields, data, len(cells[0]) if cells else 0, source)
        return self._table

    def to_pandas(self):
        """The data as a pandas DataFrame (`series`, `time` a column as
        fmpy's result gives it; or a sweep's `table`). Needs pandas."""
        return as_pandas(self.table if self.is_sweep else self.series)

    def _has_series_file(self) -> bool:
        return any((self.path / n).is_file() for n in SERIES_FILES)

    def _strip(self) -> str | None:
        fmus = self.summary.get("fmus")
        return next(iter(fmus)) if isinstance(fmus, dict) and len(fmus) == 1 else None

    # -- a quick figure ------------------------------------------------------------

    def plot(self, *columns: str, ax=None):
        """A matplotlib figure of the chosen columns (names or shell
        patterns; none: every number) against time (a run) or the sweep's
        first axis (a sweep), one axes per unit; with `ax` (a matplotlib
        Axes, e.g. pyplot's), all on that axes. Returns the Figure."""
        for c in columns:
            if not isinstance(c, str):
                raise UsageError(f"Result.plot(): {shorten(repr(c), 80)}: expected column names (strings)")
        data = self.table if self.is_sweep else self.series
        names = list(data.dtype.names)
        x_name = names[0]
        chosen = [n for n in names[1:] if data.dtype[n].kind in "biuf" and data.dtype[n].shape == ()
                  and (not columns or any(n == c or fnmatch.fnmatchcase(n, c) for c in columns))]
        if not chosen:
            numeric = [n for n in names[1:] if data.dtype[n].kind in "biuf"]
            raise UsageError(f"Result.plot({', '.join(map(repr, columns))}): no column matches: the numeric columns "
                             f"are {shorten(', '.join(numeric), 300) or 'none'}")
        info = self.summary.get("columns", {}) if not self.is_sweep else {}
        strip = self._strip()

        def unit(n):
            meta = info.get(n) or info.get(f"{strip}.{n}") or {}
            return meta.get("unit") or "" if isinstance(meta, dict) else ""

        from .plots.registry import load_matplotlib, plain

        load_matplotlib()
        from matplotlib.figure import Figure

        x = np.asarray(data[x_name], dtype=float)
        x_label = "time (s)" if x_name == "time" else plain(x_name)
        if ax is not None:
            for n in chosen:
                ax.plot(x, np.asarray(data[n], dtype=float), label=plain(n))
            ax.set_xlabel(x_label)
            ax.legend(fontsize=8)
            return ax.figure
        groups: dict[str, list[str]] = {}
        for n in chosen:
            groups.setdefault(unit(n), []).append(n)
        fig = _Figure(figsize=(9, 1.0 + 1.8 * len(groups)))
        axes = fig.subplots(len(groups), 1, sharex=True, squeeze=False)[:, 0]
        marker = "o-" if self.is_sweep else "-"
        for a, (u, members) in zip(axes, groups.items()):
            for n in members:
                a.plot(x, np.asarray(data[n], dtype=float), marker, lw=1.0, ms=3, label=plain(n))
            a.set_ylabel(plain(u) if u else "(no unit)" if not self.is_sweep else "", fontsize=8)
            a.grid(True, lw=0.3, color="0.85")
            a.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
        axes[-1].set_xlabel(x_label)
        fig.suptitle(plain(self.title), fontsize=10)
        fig.tight_layout()
        return fig

    # -- how it shows itself ---------------------------------------------------------

    def __repr__(self) -> str:
        lines = [f"clockwork result {self.path}: {printable(shorten(self.title, 120))}"]
        if self.failed:
            lines.append(f"  failed: {shorten(self.failed, 200)}")
        if self.is_sweep:
            lines.append(f"  sweep of {self.summary.get('points_total', len(self.summary.get('points', [])))} points"
                         f" ({self.summary.get('points_failed', 0)} failed): .table")
        else:
            cols = self.summary.get("columns", {})
            src = next((n for n in SERIES_FILES if (self.path / n).is_file()), None)
            lines.append(f"  time series of {len(cols)} recorded variables: .series" + (f" ({src})" if src else " (none kept)"))
        plots = self.plots
        if plots:
            lines.append(f"  plots: {shorten(', '.join(p.name for p in plots), 200)}")
        return "\n".join(lines)

    def _repr_pretty_(self, p, cycle: bool) -> None:
        p.text(repr(self))

    def _repr_html_(self) -> str:
        e = html.escape
        out = [f"<div><p><b>{e(printable(shorten(self.title, 300)))}</b> <code>{e(str(self.path))}</code></p>"]
        if self.failed:
            out.append(f"<p><b>failed:</b> {e(shorten(self.failed, 500))}</p>")
        out.append("<table>")
        for key, value in _summary_rows(self.summary):
            out.append(f"<tr><th style='text-align:left'>{e(key)}</th><td style='text-align:left'>{e(value)}</td></tr>")
        out.append("</table>")
        if self.is_sweep and (self.path / "sweep.csv").is_file():
            try:
                table = self.table
            except UsageError as err:
                out.append(f"<p>{e(str(err))}</p>")
            else:
                out.append(_html_table(table, MAX_TABLE_ROWS))
        shown = 0
        for p in self.plots:
            size = p.stat().st_size
            if shown >= MAX_INLINE_PLOTS or size > MAX_INLINE_BYTES:
                out.append(f"<p>{e(p.name)} (not shown: {size:,} bytes)</p>" if shown < MAX_INLINE_PLOTS
                           else f"<p>{e(p.name)}</p>")
                continue
            try:
                with open_regular(p, "a PNG file", MAX_INLINE_BYTES) as f:
                    data = f.read(MAX_INLINE_BYTES + 1)
            except OSError as err:
                out.append(f"<p>{e(p.name)}: {e(str(err))}</p>")
                continue
            if not data.startswith(b"\x89PNG\r\n\x1a\n"):
                out.append(f"<p>{e(p.name)}: not a PNG file</p>")
                continue
            out.append(f"<p>{e(p.name)}<br><img src='data:image/png;base64,{base64.b64encode(data).decode()}' "
                       f"alt='{e(p.name)}' style='max-width:100%'></p>")
            shown += 1
        out.append("</div>")
        return "\n".join(out)


class _Figure:  # replaced by a matplotlib Figure subclass on first use (matplotlib imported late)
    def __new__(cls, *args, **kwargs):
        global _Figure
        from matplotlib.figure import Figure

        class Shown(Figure):
            """A Figure that a notebook shows as a PNG without pyplot."""

            def _repr_png_(self):
                import io

                buf = io.BytesIO()
                self.savefig(buf, format="png", dpi=100, bbox_inches="tight")
                return buf.getvalue()

        Shown.__name__ = Shown.__qualname__ = "Figure"
        _Figure = Shown
        return Shown(*args, **kwargs)


def _summary_rows(summary: dict) -> list[tuple[str, str]]:
    """(key, value) rows of the summary a person reads first."""
    rows = []

    def add(key, value):
        if value not in (None, "", [], {}):
            rows.append((key, shorten(printable(value if isinstance(value, str) else _text(value)), 300)))

    add("scene", summary.get("scene"))
    tool = summary.get("tool", {})
    add("clockwork", tool.get("version") if isinstance(tool, dict) else None)
    fmus = summary.get("fmus")
    if isinstance(fmus, dict):
        add("FMUs", ", ".join(f"{k} ({v.get('model')})" if isinstance(v, dict) else str(k) for k, v in fmus.items()))
    settings = summary.get("settings", {})
    if isinstance(settings, dict):
        add("experiment", settings.get("experiment"))
        master = settings.get("master")
        if isinstance(master, dict):
            add("master", {k: master[k] for k in ("engine", "step", "tolerance") if k in master})
        add("overrides", settings.get("overrides"))
    result = summary.get("result")
    if isinstance(result, dict):
        for k, v in result.items():
            add(f"result: {k}", v)
    for k in ("points_total", "points_failed", "points_reused"):
        add(k.replace("_", " "), summary.get(k))
    headlines = summary.get("headlines")
    if isinstance(headlines, list):
        for h in headlines[:20]:
            add("headline", h)
    stats = summary.get("statistics")
    if isinstance(stats, dict):
        add("statistics", stats)
    if isinstance(summary.get("wall_time_s"), (int, float)):
        add("wall time", f"{summary['wall_time_s']:.3g} s")
    add("files", ", ".join(x for x in summary.get("files", []) if isinstance(x, str)))
    for k in ("plots_failed", "plots_not_drawn", "plots_notes"):
        add(k.replace("_", " "), summary.get(k))
    return rows


def _text(value) -> str:
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, dict):
        return ", ".join(f"{k} = {_text(v)}" for k, v in value.items())
    if isinstance(value, list):
        return ", ".join(_text(v) for v in value)
    return str(value)


def _html_table(table: np.ndarray, limit: int) -> str:
    e = html.escape
    names = table.dtype.names
    head = "".join(f"<th>{e(printable(n))}</th>" for n in names)
    body = []
    for row in table[:limit]:
        body.append("<tr>" + "".join(f"<td>{e(printable(shorten(_cell(x), 60)))}</td>" for x in row) + "</tr>")
    more = f"<p>... {len(table) - limit} more rows (.table)</p>" if len(table) > limit else ""
    return f"<table><tr>{head}</tr>{''.join(body)}</table>{more}"


def _cell(x) -> str:
    if x is None:
        return ""
    if isinstance(x, (float, np.floating)):
        return f"{float(x):.6g}"
    return str(x)


# -- reading the files -------------------------------------------------------------------


def _read_series(path: Path, info: dict) -> dict[str, np.ndarray | list]:
    """{column: values} of a timeseries file, `time` first; `info`:
    summary.json's columns (a String column is text, any other numbers)."""
    suffix = path.suffix
    if suffix == ".parquet":
        columns = _read_parquet(path)
    elif suffix == ".mat":
        columns = _read_mat(path)
    else:
        header, cells = _read_csv(path)
        columns = {}
        for j, (name, col) in enumerate(zip(header, cells)):
            meta = info.get(name)
            if isinstance(meta, dict) and meta.get("type") in _TEXT:
                columns[name] = list(col)
                continue
            numbers = _numbers(col)
            if numbers is None:
                k, cell = next((k, c) for k, c in enumerate(col) if c and _number(c) is None)
                raise UsageError(f"{path}: line {k + 2}, column {j + 1} ({shorten(name, 60)}): expected a number, "
                                 f"got {shorten(cell, 40)!r}")
            columns[name] = numbers
        if len(columns) != len(header):
            raise UsageError(f"{path}: line 1: a column name given twice: expected one column per variable")
    names = list(columns)
    if not names or names[0] != "time":
        raise UsageError(f"{path}: the first column is {shorten(repr(names[0]), 60) if names else 'missing'}: expected "
                         "time (a time series clockwork wrote)")
    return columns


def _read_csv(path: Path) -> tuple[list[str], list[list[str]]]:
    """The header and the columns (as text) of a CSV file clockwork wrote."""
    try:
        with open_regular(path, "a CSV file clockwork wrote") as raw, \
                open(raw.fileno(), encoding="utf-8", newline="", closefd=False) as f:
            rows = csv.reader(f, strict=True)
            header = next(rows, None)
            if not header:
                raise UsageError(f"{path}: line 1: expected a header line (a CSV file clockwork wrote)")
            cells: list[list[str]] = [[] for _ in header]
            for k, row in enumerate(rows, start=2):
                if len(row) != len(header):
                    raise UsageError(f"{path}: line {k}: {len(row)} values for {len(header)} columns")
                for col, cell in zip(cells, row):
                    col.append(cell)
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        raise UsageError(f"{path}: cannot read: {getattr(e, 'strerror', None) or e}") from None
    return header, cells


def _numbers(cells: list[str]) -> np.ndarray | None:
    """A column of text as float64 (empty fields NaN: what clockwork writes
    for a missing value), or None when a field is not a number."""
    out = np.empty(len(cells), dtype=np.float64)
    for i, c in enumerate(cells):
        x = _number(c) if c else math.nan
        if x is None:
            return None
        out[i] = x
    return out


def _number(cell: str) -> float | None:
    try:
        return parse_real(cell, CSV_SPECIAL)
    except ValueError:
        return None


def _read_parquet(path: Path) -> dict[str, np.ndarray | list]:
    try:
        import pyarrow.parquet as pq
    except ImportError:
        raise UsageError(f"{path}: reading Parquet needs pyarrow: pip install 'clockwork-fmi[parquet]' "
                         "(or pip install pyarrow)") from None
    try:
        with open_regular(path, "a Parquet file clockwork wrote") as f:
            table = pq.read_table(f)
    except OSError as e:
        raise UsageError(f"{path}: cannot read: {getattr(e, 'strerror', None) or e}") from None
    except Exception as e:  # noqa: BLE001 (pyarrow's own errors for a file that is not Parquet)
        raise UsageError(f"{path}: not a Parquet file clockwork wrote: {shorten(e, 120)}") from None
    out: dict[str, np.ndarray | list] = {}
    for name, column in zip(table.column_names, table.columns):
        if name in out:
            raise UsageError(f"{path}: the column {shorten(repr(name), 60)} twice: expected one per variable")
        values = column.to_pylist() if column.null_count or not _arrow_numeric(column.type) else None
        if values is None:
            out[name] = column.to_numpy()
        elif all(v is None or isinstance(v, (int, float, bool)) for v in values):
            out[name] = np.asarray([math.nan if v is None else v for v in values], dtype=np.float64)
        else:
            out[name] = values
    return out


def _arrow_numeric(t) -> bool:
    import pyarrow.types as pt

    return pt.is_integer(t) or pt.is_floating(t) or pt.is_boolean(t)


def _read_mat(path: Path) -> dict[str, np.ndarray | list]:
    """A result file in the layout Modelica tools write (Dymola's dsres,
    OpenModelica's _res.mat): Aclass ("Atrajectory", version, "",
    "binTrans" or "binNormal"), name and description (character
    matrices, a name per column with binTrans), dataInfo (per variable:
    its data block, its column there, 1-based, negative for a negated
    alias), data_1 (constants: first and last time) and data_2 (the
    trajectories; a variable per row with binTrans), time in data_2's
    first signal."""
    try:
        import scipy.io
    except ImportError:
        raise UsageError(f"{path}: reading a MAT file needs SciPy: pip install scipy") from None
    bad = f"{path}: not a result file in the Modelica layout"
    try:
        with open_regular(path, "a MAT file clockwork wrote") as f:
            mat = scipy.io.loadmat(f, chars_as_strings=False)
    except OSError as e:
        raise UsageError(f"{path}: cannot read: {getattr(e, 'strerror', None) or e}") from None
    except Exception as e:  # noqa: BLE001 (scipy's own errors for a file that is not MAT)
        raise UsageError(f"{bad}: {shorten(e, 120)}") from None
    for key in ("Aclass", "name", "dataInfo"):
        if key not in mat:
            raise UsageError(f"{bad}: no {key}")
    aclass = _char_rows(mat["Aclass"])
    if not aclass or aclass[0] != "Atrajectory":
        raise UsageError(f"{bad}: Aclass: expected Atrajectory first")
    trans = len(aclass) > 3 and aclass[3] == "binTrans"
    names = _char_rows(mat["name"].T if trans else mat["name"])
    info = np.asarray(mat["dataInfo"])
    info = info.T if trans else info
    if info.ndim != 2 or info.shape[0] != len(names) or info.shape[1] < 2:
        raise UsageError(f"{bad}: dataInfo: expected a row of (block, column, ...) per name")
    blocks: dict[int, np.ndarray] = {}
    out: dict[str, np.ndarray | list] = {}
    n_rows = None
    for name, (block, column) in zip(names, info[:, :2].astype(np.int64)):
        block = 2 if block == 0 else int(block)  # 0: the abscissa, time: data_2's first signal
        if block not in blocks:
            data = mat.get(f"data_{block}")
            if data is None or np.asarray(data).ndim != 2:
                raise UsageError(f"{bad}: {name}: no data_{block}")
            data = np.asarray(data, dtype=np.float64)
            blocks[block] = data if trans else data.T  # a signal per row
        data = blocks[block]
        if not 1 <= abs(column) <= data.shape[0]:
            raise UsageError(f"{bad}: {name}: column {column} of data_{block}, which has {data.shape[0]}")
        values = data[abs(column) - 1] * (-1.0 if column < 0 else 1.0)
        if block == 2:
            n_rows = len(values)
        elif n_rows is not None:  # a constant: its value at every row
            values = np.full(n_rows, values[0])
        out[name] = values
    for name, values in out.items():  # constants read before the first trajectory
        if n_rows is not None and len(values) != n_rows:
            out[name] = np.full(n_rows, values[0])
    if "time" in out:
        out = {"time": out.pop("time"), **out}
    return out


def _char_rows(matrix) -> list[str]:
    """A character matrix (loadmat's chars_as_strings=False) as its rows, blanks and NULs stripped."""
    a = np.asarray(matrix)
    if a.ndim == 3 and a.shape[2] == 1:  # an array of one-character strings, as savemat may write one
        a = a[:, :, 0]
    if a.ndim == 1:
        a = a[np.newaxis, :]
    if a.ndim != 2 or a.dtype.kind not in "US":
        return []
    return ["".join(str(c) for c in row).rstrip(" \x00") for row in a]


def _structured(columns: dict, info: dict, strip: str | None, source: Path) -> np.ndarray:
    """The columns as clockwork.simulate's result: time first, each column
    of its FMI type (summary.json's columns) where its values are exact in it."""
    fields, data = [], []
    n = len(columns["time"])
    for name, values in columns.items():
        meta = info.get(name) if isinstance(info, dict) else None
        kind = meta.get("type") if isinstance(meta, dict) else None
        label = name[len(strip) + 1:] if strip and name.startswith(strip + ".") and name != f"{strip}.time" else name
        if len(values) != n:
            raise UsageError(f"{source}: {shorten(name, 60)}: {len(values)} values for {n} times")
        if kind in _TEXT or not isinstance(values, np.ndarray) or values.dtype == object:
            fields.append((label, object))
            data.append(np.asarray(list(values), dtype=object))
            continue
        values = np.asarray(values)
        dtype = _DTYPES.get(kind)
        if dtype is not None and values.dtype != dtype:
            # integers and booleans come back as they were (CSV and MAT keep them as doubles,
            # Parquet as its own width), where every value is exact in the variable's type
            finite = values.dtype.kind != "f" or bool(np.isfinite(values).all())
            with np.errstate(all="ignore"):
                cast = values.astype(dtype) if finite else None
            if cast is not None and np.array_equal(cast.astype(values.dtype), values):
                values = cast
        elif dtype is None and values.dtype.kind in "iub":
            values = values.astype(np.float64)
        fields.append((label, values.dtype))
        data.append(values)
    return _pack(fields, data, n, source)


def _pack(fields: list, data: list, n: int, source: Path) -> np.ndarray:
    names = [f[0] for f in fields]
    if len(set(names)) != len(names):
        twice = next(x for x in names if names.count(x) > 1)
        raise UsageError(f"{source}: the column {shorten(repr(twice), 60)} twice: expected one per variable")
    out = np.empty(n, dtype=fields)
    for (name, _), values in zip(fields, data):
        out[name] = values
    return out


def _has(module: str) -> bool:
    import importlib.util

    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def pandas_module(call: str = "to_pandas()"):
    """pandas, or one UsageError saying how to install it."""
    try:
        import pandas
    except ImportError:
        raise UsageError(f"{call} needs pandas: pip install pandas") from None
    return pandas


def as_pandas(result: np.ndarray, call: str = "to_pandas()"):
    """A structured array (clockwork.simulate's result) as a DataFrame,
    `time` a column; a field of an FMI 3.0 array as a column per element
    (``y[0]``, ``A[1,2]``, fmpy's element names)."""
    pd = pandas_module(call)
    columns = {}
    for name in result.dtype.names:
        shape = result.dtype[name].shape
        if shape:
            for idx in np.ndindex(*shape):
                columns[f"{name}[{','.join(map(str, idx))}]"] = result[name][(slice(None), *idx)]
        else:
            columns[name] = result[name]
    return pd.DataFrame(columns)

