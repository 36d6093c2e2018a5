"""A run's recorded series, written to disk as the run goes.

``SeriesWriter`` takes the recorder's rows a chunk at a time (the recorder
keeps at most one chunk in memory) and appends them to each result format
asked for, in the output directory's staging folder (results.outdir), so a
run's memory does not grow with its length:

- ``timeseries.csv``: the same bytes the whole-run writer gave
  (files.write_csv_atomic: floats as repr, text quoted where needed);
- ``timeseries.parquet``: row groups of PARQUET_ROWS rows (pyarrow, an optional extra);
- ``timeseries.mat``: the result layout of Modelica tools (Dymola's
  "binTrans" as OpenModelica writes it too, MAT level 4): the rows go to a
  temporary binary file while the run goes, and at the end the small
  matrices (``Aclass``, ``name``, ``description``, ``dataInfo``,
  ``data_1``) are written by scipy.io.savemat and ``data_2`` (one column
  per recorded row, so the rows are its columns in file order) is copied
  after them a chunk at a time. Text columns (String, Binary) have no place
  in a numeric matrix and are left out of it.

The CSV is always written (the plots and a failed run's history read it):
as a hidden file of the staging folder, never committed, when csv is not
among the formats. A file of the staging folder is seen by nobody until
the commit; a run that fails keeps what it wrote up to its last good point
and commits it with its summary; an interrupted run's files are removed
(``abort``). Each file is written unnamed (Linux O_TMPFILE, as
atomic.write_bytes_unnamed) and given its name in ``close``, after its
fsync: a run killed by SIGKILL leaves no series file at all, and the
commit renames only complete files. Where the file system has no
O_TMPFILE, the files are named from the start (and removed with the
staging folder by the next run after a kill).
"""

from __future__ import annotations

import errno
import os
import struct
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..errors import UsageError
from .files import _field

FORMATS = ("csv", "parquet", "mat")
FILE_NAMES = {f: f"timeseries.{f}" for f in FORMATS}
# Disk bytes per recorded value at most, per format: the longest repr of a
# double and its comma (24 + 1), a double (parquet's pages, uncompressed
# plain encoding; mat's matrix and its temporary copy).
BYTES_PER_VALUE = {"csv": 25, "parquet": 8, "mat": 16}
PARQUET_ROWS = 1 << 13  # rows of a Parquet row group (larger ones cost memory: bench_memory.py)
PARQUET_HINT = "pip install 'clockwork[parquet]' (or pip install pyarrow)"


def require_formats(formats) -> None:
    """Refuse, before any work, a format whose writer is not installed."""
    if "parquet" in formats:
        try:
            import pyarrow  # noqa: F401
            import pyarrow.parquet  # noqa: F401
        except ImportError:
            raise UsageError(f"--format parquet needs pyarrow, which is not installed: {PARQUET_HINT}") from None


def estimate_bytes(rows: int, columns: int, formats) -> int:
    """Disk bytes the series of `rows` rows of `columns` values (time
    included) take at most in `formats` (the CSV always: see the module)."""
    per = BYTES_PER_VALUE["csv"] + sum(BYTES_PER_VALUE[f] for f in set(formats) - {"csv"})
    return rows * columns * per


def descriptions(scene, names: list[str]) -> dict[str, str]:
    """{column: "description [unit]"} of recorded "instance.variable"
    columns, as Modelica tools write a result's descriptions."""
    from ..fmi.description import var_unit, variables
    from ..engine.names import split_ref

    found = {n: variables(c.model_description) for n, c in scene.components.items()}
    out = {}
    for name in names:
        split = split_ref(name, found)
        v = found[split[0]].get(split[1]) if split else None
        if v is not None:
            unit = var_unit(v)
            text = (getattr(v, "description", None) or "").strip()
            out[name] = f"{text} [{unit}]".strip() if unit else text
    return out


class SeriesWriter:
    """The sink of an engine.recording.Recorder: ``write(columns)`` a chunk
    (time first, then each name's column), ``close()`` gives the
    ``StreamedSeries``, ``abort()`` removes what was written."""

    def __init__(self, folder: Path, names: list[str], text: set[str], formats=("csv",),
                 descriptions: dict[str, str] | None = None):
        self.folder = Path(folder)
        self.header = ["time", *names]
        self.text = [n in text for n in self.header]
        self.formats = tuple(dict.fromkeys(formats))
        self.descriptions = descriptions or {}
        self.rows = 0
        self._t0 = self._t_end = 0.0
        self.files: list[Path] = []
        self.csv = self.folder / ("timeseries.csv" if "csv" in self.formats else ".timeseries.csv")
        self._unnamed: dict[int, Path] = {}  # id of an unnamed file object -> the name it gets in close
        self._csv = self._open(self.csv)
        self._put(self._csv, self.csv, (",".join(_field(h) for h in self.header) + "\n").encode("utf-8"))
        self._parquet = None
        if "parquet" in self.formats:
            import pyarrow as pa  # an optional extra: require_formats checked it

            # The system's allocator: Arrow's own pools keep what a row group freed (+20 MB a run).
            pa.set_memory_pool(pa.system_memory_pool())

            fields = [pa.field(n, pa.string() if t else pa.float64()) for n, t in zip(self.header, self.text)]
            self._schema = pa.schema(fields)
            self._parquet_path = self.folder / FILE_NAMES["parquet"]
            import pyarrow.parquet as pq

            self._parquet_file = self._open(self._parquet_path)
            self._pending: list = []  # tables of the row group being gathered
            self._pending_rows = 0
            try:
                self._parquet = pq.ParquetWriter(self._parquet_file, self._schema, use_dictionary=False)
            except OSError as e:
                raise OSError(e.errno, e.strerror or str(e), str(self._parquet_path)) from None
        self._mat = None
        if "mat" in self.formats:
            self._mat_rows = self.folder / ".timeseries.mat.rows"
            self._mat = self._open(self._mat_rows, readable=True)
            self._numeric = [i for i, t in enumerate(self.text) if not t]

    def _open(self, path: Path, readable: bool = False):
        """A file to be called `path` once complete (``_name``): unnamed until
        then where the system can; `readable`, read back too."""
        flag = getattr(os, "O_TMPFILE", None)
        try:
            if flag is not None and os.path.isdir("/proc/self/fd"):
                try:
                    f = open(os.open(path.parent, flag | (os.O_RDWR if readable else os.O_WRONLY), 0o644),
                             "w+b" if readable else "wb")
                    self._unnamed[id(f)] = path
                    return f
                except OSError as e:
                    if e.errno not in (errno.EOPNOTSUPP, errno.EISDIR, errno.EINVAL):
                        raise
            f = open(path, "x+b" if readable else "xb")
        except OSError as e:
            raise OSError(e.errno, e.strerror, str(path)) from None
        self.files.append(path)
        return f

    def _name(self, f, path: Path) -> None:
        """Flush, fsync and (an unnamed file) link `f` in as `path`; then close it."""
        try:
            f.flush()
            os.fsync(f.fileno())
            if self._unnamed.pop(id(f), None) is not None:
                folder = os.open(path.parent, os.O_RDONLY | os.O_DIRECTORY)
                try:
                    # with a dir_fd, linkat(AT_SYMLINK_FOLLOW): the open file, not /proc's link
                    os.link(f"/proc/self/fd/{f.fileno()}", path.name, dst_dir_fd=folder)
                finally:
                    os.close(folder)
                self.files.append(path)
            f.close()
        except OSError as e:
            raise OSError(e.errno, e.strerror, str(path)) from None

    @staticmethod
    def _put(f, path: Path, data: bytes) -> None:
        try:
            f.write(data)
        except OSError as e:  # a full disk, a file size limit: named by the file
            raise OSError(e.errno, e.strerror, str(path)) from None

    def write(self, columns: list[list]) -> None:
        n = len(columns[0])
        if not n:
            return
        if not self.rows:
            self._t0 = float(columns[0][0])
        self._t_end = float(columns[0][n - 1])
        self.rows += n
        # As files._csv_chunks: numbers through a float array (None as NaN), text by _field.
        cols = [c if t else np.asarray(c, dtype=float) for c, t in zip(columns, self.text)]
        fields = [[_field(x) for x in c] if t else list(map(repr, c.tolist())) for c, t in zip(cols, self.text)]
        self._put(self._csv, self.csv, "".join(",".join(row) + "\n" for row in zip(*fields)).encode("utf-8"))
        if self._parquet is not None:
            import pyarrow as pa

            arrays = [pa.array(c, type=pa.string()) if t else pa.array(c, type=pa.float64())
                      for c, t in zip(cols, self.text)]
            # Row groups of PARQUET_ROWS rows: one per chunk would be small for readers.
            self._pending.append(pa.Table.from_arrays(arrays, schema=self._schema))
            self._pending_rows += n
            if self._pending_rows >= PARQUET_ROWS:
                self._write_row_group()
        if self._mat is not None:
            block = np.column_stack([cols[i] for i in self._numeric]).astype("<f8", copy=False)
            self._put(self._mat, self._mat_rows, block.tobytes(order="C"))

    def _write_row_group(self) -> None:
        import pyarrow as pa

        table, self._pending, self._pending_rows = pa.concat_tables(self._pending), [], 0
        try:
            self._parquet.write_table(table, row_group_size=max(1, table.num_rows))
        except OSError as e:
            raise OSError(e.errno, e.strerror or str(e), str(self._parquet_path)) from None

    def close(self) -> "StreamedSeries":
        """Finish every file (fsynced, then named) and give the series they hold."""
        self._name(self._csv, self.csv)
        self._csv = None
        if self._parquet is not None:
            if self._pending:
                self._write_row_group()
            try:
                self._parquet.close()
            except OSError as e:
                raise OSError(e.errno, e.strerror or str(e), str(self._parquet_path)) from None
            self._parquet = None
            self._name(self._parquet_file, self._parquet_path)
        if self._mat is not None:
            rows, self._mat = self._mat, None
            try:
                rows.flush()
                rows.seek(0)
                mat = self.folder / FILE_NAMES["mat"]
                out = self._open(mat)
                self._mat_out = out
                write_mat(out, rows, [self.header[i] for i in self._numeric], self.rows,
                          (self._t0, self._t_end), self.descriptions)
            except OSError as e:
                raise OSError(e.errno, e.strerror, str(self.folder / FILE_NAMES["mat"])) from None
            self._name(out, mat)
            self._mat_out = None
            self._drop(rows, self._mat_rows)
        named = {p.name for p in self.files}
        return StreamedSeries(self.csv, self.header, self.text,
                              [FILE_NAMES[f] for f in self.formats if FILE_NAMES[f] in named])

    def _drop(self, f, path: Path) -> None:
        """Close `f` and remove it (an unnamed file vanishes as it closes)."""
        named = self._unnamed.pop(id(f), None) is None
        try:
            f.close()
        except OSError:
            pass
        if named:
            try:
                path.unlink()
            except OSError:
                pass
            if path in self.files:
                self.files.remove(path)

    def abort(self) -> None:
        """Close and remove everything written (a run that was interrupted)."""
        if self._parquet is not None:
            try:
                self._parquet.close()
            except Exception:  # noqa: BLE001 (a writer that failed: its file goes anyway)
                pass
            self._parquet = None
        for f, path in ((self._csv, self.csv), (getattr(self, "_parquet_file", None), getattr(self, "_parquet_path", None)),
                        (self._mat, getattr(self, "_mat_rows", None)), (getattr(self, "_mat_out", None),
                                                                         self.folder / FILE_NAMES["mat"])):
            if f is not None and not f.closed:
                self._drop(f, path)
        for p in list(self.files):
            try:
                p.unlink()
            except OSError:
                pass
        self.files.clear()


# MAT level 4: a matrix is a header of five int32 (type MOPT, rows, columns,
# imaginary flag, name length with its NUL), the name, then the data column
# by column. Type 0: little-endian IEEE doubles, a full numeric matrix.
_MAT4_DOUBLE = 0
_COPY_BYTES = 1 << 22


def write_mat(f, rows, names: list[str], n_rows: int, span: tuple[float, float],
              descriptions: dict[str, str]) -> None:
    """The result file of Modelica tools into the file `f`: every column in
    data_2 (time first; its data the row-major doubles the file `rows`
    holds, copied a block at a time), data_1 the start and end time alone
    (no parameters are recorded)."""
    from scipy.io import savemat  # scipy is imported only by runs that ask for MAT

    def chars(texts: list[str]) -> np.ndarray:
        # One text per column of the stored matrix (transposed, as binTrans says), blank-padded.
        width = max(1, *(len(t) for t in texts))
        # contiguous: savemat writes a transposed view's characters in the wrong order
        return np.ascontiguousarray(np.array([list(t.ljust(width)) for t in texts], dtype="U1").T)

    info = np.array([[0, 1, 0, -1]] + [[2, k + 1, 0, -1] for k in range(1, len(names))], dtype=np.int32).T.copy()
    header = {
        "Aclass": np.array([list("Atrajectory"), list("1.1        "), list(" " * 11), list("binTrans   ")],
                           dtype="U1"),
        "name": chars(names),
        "description": chars([descriptions.get(n, "Time in [s]" if n == "time" else "") for n in names]),
        "dataInfo": info,
        "data_1": np.array([[span[0], span[1]]], dtype=float),
    }
    savemat(f, header, format="4")
    name = b"data_2\0"
    f.write(struct.pack("<5i", _MAT4_DOUBLE, len(names), n_rows, 0, len(name)) + name)
    while True:
        block = rows.read(_COPY_BYTES)
        if not block:
            break
        f.write(block)


class StreamedSeries(Mapping):
    """A recorded series that is on disk: {name: its values}, read from the
    CSV on first use (the plots, `clockwork.simulate`); `files`: the result
    files written. Pickled as its paths (the plot process reads it)."""

    def __init__(self, csv: Path, header: list[str], text: list[bool], files: list[str]):
        self.csv, self.header, self.text, self.files = Path(csv), list(header), list(text), list(files)
        self._columns: dict | None = None

    def __getstate__(self):
        return {**self.__dict__, "_columns": None}

    def committed(self, folder: Path) -> None:
        """The files moved into `folder` (the output directory's commit): read
        from there; the CSV was there only when asked for, else the first
        other format is read."""
        self.csv = Path(folder) / "timeseries.csv"
        self.folder = Path(folder)

    def _load(self) -> dict:
        if self._columns is None and not self.csv.exists() and getattr(self, "folder", None) is not None:
            self._columns = self._load_other()
        if self._columns is None:
            import csv

            cols: list[list] = [[] for _ in self.header]
            with open(self.csv, newline="", encoding="utf-8") as f:
                reader = csv.reader(f)
                next(reader)
                for row in reader:
                    for c, x in zip(cols, row):
                        c.append(x)
            self._columns = {n: (c if t else [float(x) for x in c])
                             for n, c, t in zip(self.header, cols, self.text)}
        return self._columns

    def _load_other(self) -> dict:
        if "timeseries.parquet" in self.files:
            import pyarrow.parquet as pq

            table = pq.read_table(self.folder / "timeseries.parquet")
            return {n: table.column(n).to_pylist() for n in self.header}
        from scipy.io import loadmat

        mat = loadmat(self.folder / "timeseries.mat", chars_as_strings=False)
        names = ["".join(c).rstrip() for c in zip(*mat["name"])]
        return {n: mat["data_2"][k].tolist() for k, n in enumerate(names)}

    def __getitem__(self, name: str):
        if name not in self.header:
            raise KeyError(name)
        return self._load()[name]

    def __iter__(self):
        return iter(self.header)

    def __len__(self) -> int:
        return len(self.header)
