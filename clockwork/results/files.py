"""Result files: strict JSON, exact CSV, and output directories.

Every file is written atomically (clockwork.atomic). All JSON is strict:
NaN and infinities are written as null. CSV floats read back to the same
double.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path
from typing import Sequence

import numpy as np

from ..atomic import PART, write_bytes_atomic, write_bytes_unnamed, write_text_atomic  # noqa: F401 (tests import it here)
from ..errors import UsageError
from ..files import absent

def _json_default(obj):
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, (set, frozenset)):
        try:
            return sorted(obj)
        except TypeError:
            return list(obj)
    raise TypeError(f"{type(obj).__name__} is not JSON serializable")


def clean_json(x):
    """JSON has no NaN: non-finite numbers become null."""
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: clean_json(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [clean_json(v) for v in x]
    return x


def json_text(obj) -> str:
    """Strict JSON: sorted keys, indent 2, NaN and infinities as null."""
    return json.dumps(clean_json(_plain(obj)), sort_keys=True, indent=2, allow_nan=False) + "\n"


def _plain(x):
    """numpy values, paths and sets as JSON's own types (before clean_json sees them)."""
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, (np.ndarray, np.generic, Path, set, frozenset)):
        return _plain(_json_default(x))
    return x


def write_json_atomic(path: str | os.PathLike, obj, unnamed: bool = False) -> Path:
    """Strict JSON (``json_text``, the same bytes), written atomically a
    slice at a time (a point's series was text whole, then bytes, about 150
    bytes per recorded value on top of the values); with `unnamed`, into a
    file named only once complete (atomic.write_bytes_unnamed)."""
    write = write_bytes_unnamed if unnamed else write_bytes_atomic
    return write(path, _json_chunks(obj))
def _json_chunks(obj, size: int = 1 << 20):
    encoder = json.JSONEncoder(sort_keys=True, indent=2, allow_nan=False)  # as json.dumps in json_text
    buf: list[str] = []
    n = 0
    for chunk in encoder.iterencode(clean_json(_plain(obj))):
        buf.append(chunk)
        n += len(chunk)
        if n >= size:
            yield "".join(buf).encode("utf-8")
            buf.clear()
            n = 0
    buf.append("\n")
    yield "".join(buf).encode("utf-8")


def _column_strings(col) -> list[str]:
    """A column as CSV fields: floats round-trip exact (repr), integers and
    text as they are, booleans 1/0 (numbers for any CSV reader), missing
    values empty."""
    if isinstance(col, np.ndarray):
        if col.ndim != 1:
            raise ValueError(f"CSV columns must be 1-D, got shape {col.shape}")
        col = col.tolist()
    return [_field(x) for x in col]


def _field(x) -> str:
    if x is None:
        return ""
    if isinstance(x, (bool, np.bool_)):
        return "1" if x else "0"
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    if isinstance(x, (float, np.floating)):
        return repr(float(x))  # the shortest string that reads back to the same double
    if isinstance(x, str):
        return '"' + x.replace('"', '""') + '"' if any(c in x for c in ',"\n\r') else x
    raise ValueError(f"CSV fields must be numbers, text or booleans, got {type(x).__name__}")


def write_csv_atomic(path: str | os.PathLike, header: Sequence[str], columns: Sequence) -> Path:
    """Columns of equal length under a one-line header; floats written round-trip exact."""
    header = list(header)
    if len(header) != len(columns):
        raise ValueError(f"{path}: {len(header)} header names for {len(columns)} columns")
    for h in header:
        if any(c in h for c in "\n\r"):
            raise ValueError(f"{path}: header name {h!r} contains a newline")
    for c in columns:
        if isinstance(c, np.ndarray) and c.ndim != 1:
            raise ValueError(f"CSV columns must be 1-D, got shape {c.shape}")
    lengths = {len(c) for c in columns}
    if len(lengths) > 1:
        raise ValueError(f"{path}: columns of different lengths {sorted(lengths)}")
    head = ",".join(_field(h) for h in header)  # FMI names such as a[1,2] are quoted
    return write_bytes_atomic(path, _csv_chunks(head, columns, lengths.pop() if lengths else 0))


_CSV_VALUES = 1 << 16  # values made into text at a time: the file is never whole in memory


def _csv_chunks(head: str, columns: Sequence, n: int):
    """The CSV's bytes in chunks of about _CSV_VALUES values: as "\n".join of every line, plus a final newline."""
    yield (head + "\n").encode("utf-8")
    rows = max(1, _CSV_VALUES // max(1, len(columns)))
    for a in range(0, n, rows):
        cols = [_column_strings(c[a:a + rows]) for c in columns]
        yield ("".join(",".join(row) + "\n" for row in zip(*cols))).encode("utf-8")


def check_output_dir(path: str | os.PathLike) -> Path:
    """Make sure `path` is a writable directory, creating it and its parents."""
    if not str(path).strip():
        raise UsageError("the output directory is empty: give a directory, e.g. --out out/run")
    path = Path(path)
    if path.exists():
        if not path.is_dir():
            raise UsageError(f"output directory {path} exists and is not a directory")
    else:
        blocker = next((p for p in reversed(path.parents) if p.exists() and not p.is_dir()), None)
        if blocker is not None:
            raise UsageError(f"cannot create output directory {path}: {blocker} is a file, not a directory")
        try:
            path.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise UsageError(f"cannot create output directory {path}: {e.strerror or e}") from None
    # Try it: os.access misjudges some filesystems, and a failed probe is the real answer.
    probe = None
    try:
        fd, probe = tempfile.mkstemp(prefix=f".clockwork-probe.{os.getpid()}.", suffix=PART, dir=path)
        os.close(fd)
    except OSError as e:
        raise UsageError(f"output directory {path} is not writable: {e.strerror or e}") from None
    finally:
        # Removed also when a signal (SIGTERM: Interrupted) lands between the two calls.
        if probe is not None:
            try:
                os.unlink(probe)
            except OSError:
                pass
    return path


def check_output_file(path: str | os.PathLike, option: str) -> Path:
    """Make sure a file can be written at `path` (given as `option`, e.g.
    ``--json``) before any work: not a directory, in a directory that exists
    and is writable. Refused as bad input naming the option and the path,
    never as the failed rename of a temporary .part file."""
    if not str(path).strip():
        raise UsageError(f"{option}: an empty file name: give a file, e.g. {option} out/grade.json")
    path = Path(path)
    if path.is_dir():
        raise UsageError(f"{option} {path}: is a directory: expected a file name")
    if path.exists() and not path.is_file():  # a FIFO, a device, a socket: written by a rename over it
        raise UsageError(f"{option} {path}: {absent(path, 'a file name (a regular file, or none)')}")
    if not path.parent.is_dir():
        raise UsageError(f"{option} {path}: no such directory: {path.parent}")
    try:
        fd, probe = tempfile.mkstemp(prefix=f".clockwork-probe.{os.getpid()}.", suffix=PART, dir=path.parent)
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        raise UsageError(f"{option} {path}: its directory {path.parent} is not writable: {e.strerror or e}") from None
    return path
