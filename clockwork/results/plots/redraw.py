"""`clockwork plot RESULT_DIR`: a finished run's outputs drawn again, grouped
by unit (plots/outputs.py), from its files alone: timeseries.csv for the
values, summary.json for the title and each column's unit and type.

Everything read is checked before it is used: summary.json's size before
it is read (``MAX_SUMMARY_BYTES``), then the shape of what is drawn from it
(the title, each column's unit, type and variability); a file that is not
what clockwork writes is refused in one line. Titles and names are drawn
as plain text, cut to a bounded length (registry.plain).

The pages are written atomically. Only files written by this drawing are
touched: pages of an earlier drawing under the same name beyond the new
count (``<stem>_4.png`` when there are three now) are left as they are,
with one note (they may be someone else's files).
"""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

from ...errors import UsageError, say
from ...files import absent
from ...numbers import CSV_SPECIAL, parse_json, parse_real, shorten
from .outputs import columns, output_pages
from .registry import load_matplotlib, page_names, quiet_matplotlib, save

MAX_SERIES_BYTES = 1 << 31  # a timeseries.csv of a run that kept at most its values in memory
# The values a run records at most (analyses.bounds.MAX_KEPT_VALUES, not
# imported: it would import every analysis): a CSV of more is not one that
# clockwork wrote, and reading it would take gigabytes.
MAX_SERIES_VALUES = 20_000_000
MAX_SUMMARY_BYTES = 1 << 26  # 64 MiB: a time series' summary holds a few lines per column
_COLUMN_KEYS = ("unit", "type", "variability")


def _summary(folder: Path) -> dict:
    path = folder / "summary.json"
    if not path.is_file():
        raise UsageError(f"{folder}: no summary.json: expected the --out directory of a clockwork run")

    too_big = UsageError(f"{path}: more than {MAX_SUMMARY_BYTES} bytes: not a summary clockwork wrote")
    try:
        if path.stat().st_size > MAX_SUMMARY_BYTES:
            raise too_big
        with open(path, "rb") as f:  # a bounded read too: a file can grow
            data = f.read(MAX_SUMMARY_BYTES + 1)
        if len(data) > MAX_SUMMARY_BYTES:
            raise too_big
        summary = parse_json(data.decode("utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as e:
        raise UsageError(f"{path}: not a summary clockwork wrote: {shorten(e, 120)}") from None
    if not isinstance(summary, dict):
        raise UsageError(f"{path}: not a summary clockwork wrote: expected a JSON object")
    for key, kind, name in (("title", str, "a string"), ("columns", dict, "an object"), ("fmus", dict, "an object")):
        if key in summary and not isinstance(summary[key], kind):
            raise UsageError(f"{path}: {key}: expected {name}, got {_json_type(summary[key])}")
    for col, meta in summary.get("columns", {}).items():
        where = f"{path}: columns[{shorten(json.dumps(col), 80)}]"
        if not isinstance(meta, dict):
            raise UsageError(f"{where}: expected an object, got {_json_type(meta)}")
        for key in _COLUMN_KEYS:
            if meta.get(key) is not None and not isinstance(meta[key], str):
                raise UsageError(f"{where}.{key}: expected a string or null, got {_json_type(meta[key])}")
    return summary


def _json_type(x) -> str:
    return {dict: "an object", list: "an array", str: "a string", bool: "true or false", int: "a number",
            float: "a number", type(None): "null"}.get(type(x), type(x).__name__)


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
            most_rows = MAX_SERIES_VALUES // len(header)
            for k, row in enumerate(rows, start=2):
                if k - 1 > most_rows:
                    raise UsageError(f"{path}: more than {MAX_SERIES_VALUES} values: not a time series "
                                     "clockwork wrote (a run records at most that many)")
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
    if target.is_dir():
        raise UsageError(f"--out {target}: is a directory: expected a file name ending .png")
    if target.exists() and not target.is_file():  # a FIFO, a device: the page would be renamed over it
        raise UsageError(f"--out {target}: {absent(target, 'a .png file name (a regular file, or none)')}")
    summary = _summary(folder)
    info = summary.get("columns", {})
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
    # matplotlib's figures: a redrawing is not the first run's wait (plots/raster.py), and a
    # program may edit what it draws
    load_matplotlib()
    pages = output_pages(series["time"], cols, summary.get("title", folder.name), raster=False)
    written = []
    with quiet_matplotlib():
        # Each page saved (and its figure let go) before the next is built: memory of one page.
        for fig, name in zip(pages, page_names(target.name, pages.count)):
            save(fig, target.parent / name)
            fig.clear()
            written.append(target.parent / name)
    if pages.note:
        say("note", f"{target}: {pages.note}; `clockwork plot {folder} --only PATTERN...` draws those")
    stale = re.compile(re.escape(target.stem) + r"_(\d+)\.png")
    earlier = sorted(f.name for f in target.parent.iterdir()
                     if (m := stale.fullmatch(f.name)) and int(m.group(1)) > len(written))
    if earlier:
        say("note", f"{target.parent}: {shorten(', '.join(earlier), 200)} not written by this drawing: "
                    "left as they are")
    return written
