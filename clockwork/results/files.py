"""Result files, written atomically: readers never see a half-written file.

Every writer puts the data into a temporary file in the target's directory
(named .<name>.<random>.part), flushes and fsyncs it, then renames it over
the target with os.replace, which is atomic on POSIX within a filesystem.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path
from typing import Sequence

import numpy as np

from ..errors import UsageError


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> Path:
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    _fsync_dir(path.parent)
    return path


def _fsync_dir(d: Path) -> None:
    # Makes the rename itself durable; not possible on every platform.
    try:
        fd = os.open(d, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    return write_bytes_atomic(path, text.encode("utf-8"))


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


def write_json_atomic(path: str | os.PathLike, obj) -> Path:
    """Sorted keys, indent 2; NaN and infinities raise ValueError (JSON has none)."""
    try:
        text = json.dumps(obj, sort_keys=True, indent=2, allow_nan=False, default=_json_default)
    except ValueError as e:
        raise ValueError(f"{path}: {e} (NaN/inf refused in JSON results)") from None
    return write_text_atomic(path, text + "\n")


def _column_strings(col) -> list[str]:
    a = np.asarray(col)
    if a.ndim != 1:
        raise ValueError(f"CSV columns must be 1-D, got shape {a.shape}")
    if a.dtype.kind == "b":
        return ["1" if x else "0" for x in a.tolist()]
    if a.dtype.kind in "iu":
        return [str(x) for x in a.tolist()]
    if a.dtype.kind == "f":
        # repr gives the shortest string that reads back to the same double
        return [repr(x) for x in a.astype(float).tolist()]
    raise ValueError(f"CSV columns must be numeric, got dtype {a.dtype}")


def write_csv_atomic(path: str | os.PathLike, header: Sequence[str], columns: Sequence) -> Path:
    """Columns of equal length under a one-line header; floats written round-trip exact."""
    header = list(header)
    if len(header) != len(columns):
        raise ValueError(f"{path}: {len(header)} header names for {len(columns)} columns")
    for h in header:
        if any(c in h for c in ',"\n\r'):
            raise ValueError(f"{path}: header name {h!r} contains a comma, quote or newline")
    cols = [_column_strings(c) for c in columns]
    lengths = {len(c) for c in cols}
    if len(lengths) > 1:
        raise ValueError(f"{path}: columns of different lengths {sorted(lengths)}")
    lines = [",".join(header)]
    lines += [",".join(row) for row in zip(*cols)]
    return write_text_atomic(path, "\n".join(lines) + "\n")


def check_output_dir(path: str | os.PathLike) -> Path:
    """Make sure `path` is a writable directory (created if its parent exists)."""
    path = Path(path)
    if path.exists():
        if not path.is_dir():
            raise UsageError(f"output directory {path} exists and is not a directory")
    else:
        parent = path.parent if str(path.parent) else Path(".")
        if not parent.is_dir():
            raise UsageError(f"cannot create output directory {path}: its parent {parent} does not exist")
        try:
            path.mkdir()
        except FileExistsError:
            pass  # created concurrently
        except OSError as e:
            raise UsageError(f"cannot create output directory {path}: {e.strerror}") from None
    # Try it: os.access misjudges some filesystems, and a failed probe is the real answer.
    try:
        fd, probe = tempfile.mkstemp(prefix=".clockwork-probe.", suffix=".part", dir=path)
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        raise UsageError(f"output directory {path} is not writable: {e.strerror}") from None
    return path
