"""`clockwork plot RESULT_DIR`: a finished run's outputs drawn again, grouped
by unit (plots/outputs.py), from its files alone: timeseries.csv for the
values, summary.json for the title and each column's unit and type.

The pages are written atomically; pages of an earlier drawing under the
same name beyond the new count (``<stem>_4.png`` when there are three
now) are removed, so that the set of pages is one drawing's.
"""

from __future__ import annotations

import csv
import re
from pathlib import Path

from ...errors import UsageError
from ...files import absent
from ...numbers import CSV_SPECIAL, parse_json, parse_real, shorten
from .outputs import columns, draw_outputs
from .registry import load_matplotlib, page_names, save

MAX_SERIES_BYTES = 1 << 31  # a timeseries.csv of a run that kept at most its values in memory


def _summary(folder: Path) -> dict:
    path = folder / "summary.json"
    if not path.is_file():
        raise UsageError(f"{folder}: no summary.json: expected the --out directory of a clockwork run")

    try:
        summary = parse_json(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as e:
        raise UsageError(f"{path}: not a summary clockwork wrote: {shorten(e, 120)}") from None
    if not isinstance(summary, dict):
        raise UsageError(f"{path}: not a summary clockwork wrote: expected a JSON object")
    return summary


def _series(path: Path, info: dict) -> dict[str, list]:
    """The columns of timeseries.csv: numbers (nan, inf and empty fields
    allowed: what clockwork writes), or text for String columns."""
    if not path.is_file():
        raise UsageError(f"{path.parent}: no timeseries.csv: the run recorded no time series (a sweep, or an "
                         "analysis that keeps none); `clockwork plot` draws recorded outputs")
    if path.stat().st_size > MAX_SERIES_BYTES:
        raise UsageError(f"{path}: more than {MAX_SERIES_BYTES} bytes: not a time series clockwork wrote")
    try:
        with open(path, encoding="utf-8", newline="") as f:
            rows = csv.reader(f, strict=True)
            header = next(rows, None)
            if not header or header[0] != "time":
                raise UsageError(f"{path}: line 1: expected a header line starting with time")
            text = [info.get(h, {}).get("type") in ("String", "Binary") for h in header]
            data: list[list] = [[] for _ in header]
            for k, row in enumerate(rows, start=2):
                if len(row) != len(header):
                    raise UsageError(f"{path}: line {k}: {len(row)} values for {len(header)} columns")
                for j, cell in enumerate(row):
                    if text[j]:
                        data[j].append(cell)
                        continue
                    try:
                        data[j].append(parse_real(cell, CSV_SPECIAL) if cell else None)
                    except ValueError:
                        raise UsageError(f"{path}: line {k}, column {j + 1} ({shorten(header[j], 60)}): expected "
                                         f"a number, got {shorten(cell, 40)!r}") from None
    except (OSError, UnicodeDecodeError, csv.Error) as e:
        raise UsageError(f"{path}: cannot read: {getattr(e, 'strerror', None) or e}") from None
    if not data[0]:
        raise UsageError(f"{path}: no rows: nothing to draw")
    return dict(zip(header, data))


def redraw(result_dir: str | Path, only: list[str] | None = None, out: str | Path | None = None) -> list[Path]:
    """Draw the run in `result_dir` into `out` (default RESULT_DIR/outputs.png
    and its further pages); returns the files written."""
    folder = Path(result_dir)
    if not folder.is_dir():
        raise UsageError(f"{folder}: no such directory: expected the --out directory of a clockwork run")
    target = Path(out) if out is not None else folder / "outputs.png"
    if target.suffix.lower() != ".png" or target.name.startswith("."):
        raise UsageError(f"--out {target}: expected a file name ending .png")
    if not target.parent.is_dir():
        raise UsageError(f"--out {target}: no such directory: {target.parent}")
    if target.exists() and not target.is_file():  # a FIFO, a device: the page would be renamed over it
        raise UsageError(f"--out {target}: {absent(target, 'a .png file name (a regular file, or none)')}")
    summary = _summary(folder)
    info = summary.get("columns") if isinstance(summary.get("columns"), dict) else {}
    series = _series(folder / "timeseries.csv", info)
    fmus = summary.get("fmus")
    strip = next(iter(fmus)) if isinstance(fmus, dict) and len(fmus) == 1 else None
    cols = columns(series, info, only, strip, patterns=True)
    if not cols:
        names = [n for n in series if n != "time"]
        if only:
            raise UsageError(f"--only {' '.join(only)}: no recorded number matches; the columns are "
                             f"{shorten(', '.join(names), 300) or 'none'}")
        raise UsageError(f"{folder / 'timeseries.csv'}: no numbers recorded: nothing to draw")
    load_matplotlib()
    title = summary.get("title") if isinstance(summary.get("title"), str) else folder.name
    figures = draw_outputs(series["time"], cols, title)
    written = []
    for fig, name in zip(figures, page_names(target.name, len(figures))):
        save(fig, target.parent / name)
        written.append(target.parent / name)
    stale = re.compile(re.escape(target.stem) + r"_(\d+)\.png")
    for f in target.parent.iterdir():
        m = stale.fullmatch(f.name)
        if m and int(m.group(1)) > len(figures) and f.is_file():
            f.unlink()
    return written
