"""Write a scene's results: summary.json, CSV files and plots.

The files go into one folder (the output directory's staging folder: see
clockwork.results.outdir). Column order in sweep.csv is fixed by the scene,
not by the order in which points finished: the sweep's axes as the scene
lists them, then the result columns by name. A plot that fails does not
take the data with it: its error is in summary.json (``plots_failed``).
The plots may be drawn by a second process meanwhile (plots.background).
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from .files import clean_json, write_csv_atomic, write_json_atomic
from .headlines import headlines_for
from .plots import Plotter
from .plots.outputs import column_info
from .series import StreamedSeries

_SCALARS = (int, float, bool, str, type(None))


def write_outputs(scene, out: Path, results: list[dict], summary: dict, t_start: float,
                  plotter: Plotter | None = None) -> None:
    """Everything into `out`; the plots by `plotter` (a plot process the run
    started early), else in this process."""
    plotter = plotter or Plotter(scene)
    plotter.submit(results, out)  # drawn meanwhile, where a plot process runs
    files = []
    if scene.sweep is None:
        r = results[0]
        # A failed run: "result" says when, where and why; the data are what it recorded until then.
        summary["result"] = {"failed": r["failed"]} if "failed" in r else r.get("result", {})
        if "error" in r:
            summary["error"] = r["error"]
        summary["statistics"] = r.get("statistics", {})
        if "series" in r:
            cols = r["series"]
            if isinstance(cols, StreamedSeries):  # written as the run went, in every format asked for
                files += cols.files
            else:
                write_csv_atomic(out / "timeseries.csv", list(cols),
                                 [list(v) if any(isinstance(x, str) for x in v)  # a String variable: text
                                  else _Numbers(v) for v in cols.values()])
                files.append("timeseries.csv")
            # Units and types of the columns: `clockwork plot` redraws from the files alone.
            summary["columns"] = column_info(scene, [n for n in cols if n != "time"])
        if r.get("ticks"):
            t = np.asarray(r["ticks"], dtype=float)
            periods = np.concatenate([[np.nan], np.diff(t)])
            write_csv_atomic(out / "ticks.csv", ["tick", "time_s", "period_s"],
                             [np.arange(1, len(t) + 1, dtype=float), t, periods])
            files.append("ticks.csv")
            if any(p["kind"] == "stability" for p in scene.plots):
                files += _stability(t, out, summary)
    else:
        summary["points"] = [{"point": r.get("point"), **({"error": r["error"]} if "error" in r else {}),
                              **({"failed": r["failed"]} if "failed" in r else {}), **r.get("result", {})}
                             for r in results]
        axes = [f"{a}.{b}" for a, b in (ax.parameter for ax in scene.sweep.axes)]
        rkeys = sorted({k for r in results for k, v in r.get("result", {}).items() if isinstance(v, _SCALARS)})
        cols = [[r["point"][k] for r in results] for k in axes]
        cols += [[_scalar(r.get("result", {}).get(k)) for r in results] for k in rkeys]
        write_csv_atomic(out / "sweep.csv", axes + rkeys, cols)
        files.append("sweep.csv")
        summary["points_failed"] = sum(1 for r in results if "error" in r)
    written, failed, empty, notes = plotter.collect()
    files += written
    if notes:
        summary["plots_notes"] = notes
    if failed:
        summary["plots_failed"] = failed
    if empty:
        summary["plots_not_drawn"] = empty
    failed = scene.sweep is None and "error" in results[0]
    summary["headlines"] = [] if failed else headlines_for(scene, summary, results)
    summary["files"] = files + ["summary.json"]
    summary["wall_time_s"] = time.perf_counter() - t_start
    write_json_atomic(out / "summary.json", clean_json(summary))


def _stability(ticks: np.ndarray, out: Path, summary: dict) -> list[str]:
    """A run whose scene asks for the stability plot: the Allan and time
    deviations of its ticks as stability.csv and summary.json's
    ``stability`` (clockwork.analyses.stability), where it has enough ticks."""
    from ..analyses import stability as st  # allantools: only for the runs that ask

    if len(ticks) < st.MIN_TICKS:
        summary["stability"] = {"ticks": len(ticks), "note": f"fewer than {st.MIN_TICKS} ticks: no deviations"}
        return []
    result = st.allan(ticks)
    cols = result["columns"]
    write_csv_atomic(out / "stability.csv", list(cols), [cols[k] for k in cols])
    summary["stability"] = result
    return ["stability.csv"]


class _Numbers:
    """A recorded column as numbers (None as NaN), made into an array a slice
    at a time as the CSV is written: a copy of every column at once cost 8
    to 16 bytes per recorded value more."""

    def __init__(self, values):
        self.values = values

    def __len__(self) -> int:
        return len(self.values)

    def __iter__(self):
        return (math.nan if x is None else float(x) for x in self.values)

    def __getitem__(self, part: slice) -> np.ndarray:
        return np.asarray([math.nan if x is None else x for x in self.values[part]], dtype=float)


def _scalar(v):
    return None if isinstance(v, float) and not math.isfinite(v) else v
