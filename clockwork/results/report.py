"""Write a scene's results: summary.json, CSV files and plots."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from .files import clean_json, write_csv_atomic, write_json_atomic
from .headlines import headlines_for
from .plots import make_plots


def write_outputs(scene, out: Path, results: list[dict], summary: dict, t_start: float) -> None:
    out.mkdir(parents=True, exist_ok=True)
    files = []
    if scene.sweep is None:
        r = results[0]
        summary["result"] = r.get("result", {})
        summary["statistics"] = r.get("statistics", {})
        if "series" in r:
            cols = r["series"]
            write_csv_atomic(out / "timeseries.csv", list(cols), [np.asarray(v, dtype=float) for v in cols.values()])
            files.append("timeseries.csv")
        if r.get("ticks"):
            t = np.asarray(r["ticks"], dtype=float)
            periods = np.concatenate([[np.nan], np.diff(t)])
            write_csv_atomic(out / "ticks.csv", ["tick", "time_s", "period_s"],
                             [np.arange(1, len(t) + 1, dtype=float), t, periods])
            files.append("ticks.csv")
    else:
        points = [r for r in results]
        summary["points"] = [{"point": r.get("point"), **({"error": r["error"]} if "error" in r else {}),
                              **r.get("result", {})} for r in points]
        keys = sorted({k for r in points for k in r.get("point", {})})
        rkeys = []
        for r in points:
            for k, v in r.get("result", {}).items():
                if k not in rkeys and isinstance(v, (int, float, bool, type(None))):
                    rkeys.append(k)
        cols = []
        for k in keys:
            cols.append(np.array([float(r["point"][k]) for r in points]))
        for k in rkeys:
            cols.append(np.array([np.nan if r.get("result", {}).get(k) is None else float(r["result"][k])
                                  for r in points]))
        write_csv_atomic(out / "sweep.csv", keys + rkeys, cols)
        files.append("sweep.csv")
        summary["points_failed"] = sum(1 for r in points if "error" in r)
    files += make_plots(scene, results, out)
    summary["headlines"] = clean_json(headlines_for(scene, summary, results))
    summary["files"] = files + ["summary.json"]
    summary["wall_time_s"] = time.perf_counter() - t_start
    write_json_atomic(out / "summary.json", clean_json(summary))
