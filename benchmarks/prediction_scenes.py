"""The bundled scenes with event prediction off and on: where prediction
changes the step sequence, how far the results move.

Each scene runs twice as `clockwork run` (a fresh process each, the point
cache off): with `master.event_prediction=false` (the switches located by
rollback, the algorithm before prediction) and with it true (the default).
Per scene it prints the number of result values that are the same bits,
the largest difference of the others, each headline that moved, checked
against its tolerance (summary.json), and the rates in s/day that moved
more than the shooting search's own `rate_tolerance_s_per_day` (not a
failure: at a coarse communication step the co-simulation's error is
larger than the search's; the scene's description states that accuracy
against the monolithic reference). Exit 1 when a headline moves beyond
its tolerance.

    python benchmarks/prediction_scenes.py --quick --out out/prediction_scenes
    python benchmarks/prediction_scenes.py --only ziemkiewicz_fig4a hoyng_appC --out out/prediction_scenes

--quick applies scenarios/quick.json's reductions (as `clockwork gallery
--quick`); without it the long scenes run in full (hoyng_fig6: minutes).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "scenarios"
SIDES = {"rollback": "false", "prediction": "true"}
# The shooting search's own measures of convergence: counted, not ranked
# among the results' differences (they sit at rounding level or count
# iterations).
DIAGNOSTICS = ("shooting_residual_rad_per_s", "rate_change_s_per_day", "shooting_iterations")


def run(stem: str, prediction: str, overrides: list[str], out: Path) -> str | None:
    """Run one scene; None, or the last stderr line of a failure."""
    command = [sys.executable, "-m", "clockwork", "run", str(SCENES / f"{stem}.toml"), "--out", str(out),
               "--no-progress", "--set", f"master.event_prediction={prediction}"]
    for o in overrides:
        command += ["--set", o]
    r = subprocess.run(command, env=dict(os.environ, CLOCKWORK_CACHE="off"), stdout=subprocess.DEVNULL,
                       stderr=subprocess.PIPE, text=True)
    if r.returncode not in (0,):
        return (r.stderr.strip().splitlines() or [f"exit code {r.returncode}"])[-1]
    return None


def numbers(d, prefix=""):
    """Flatten the numeric leaves of a JSON value: {path: float}."""
    if isinstance(d, dict):
        for k, v in d.items():
            yield from numbers(v, f"{prefix}.{k}" if prefix else k)
    elif isinstance(d, list):
        for i, v in enumerate(d):
            yield from numbers(v, f"{prefix}[{i}]")
    elif isinstance(d, (int, float)) and not isinstance(d, bool):
        yield prefix, float(d)


def results(out: Path) -> dict[str, dict]:
    """Per point (its parameters as text): the result's numbers; for a
    scene without points, its time series' columns."""
    found = {}
    for f in sorted((out / "points").glob("*.json")):
        d = json.loads(f.read_text())
        found[json.dumps(d.get("point", {}), sort_keys=True)] = d.get("result", {})
    series = out / "timeseries.csv"
    if not found and series.is_file():
        with open(series, newline="") as f:
            rows = list(csv.reader(f))
        found["time series"] = {name: [float(r[i]) for r in rows[1:]] for i, name in enumerate(rows[0])}
    return found


def compare(stem: str, out: Path) -> tuple[list[str], bool]:
    """Report lines and whether every difference is within the scene's tolerances."""
    lines, ok = [], True
    a, b = (results(out / side) for side in SIDES)
    same = total = 0
    worst: dict[str, tuple[float, float]] = {}  # field -> (|diff|, relative)
    beyond = []  # rates that moved more than the search's tolerance
    for point in a.keys() & b.keys():
        ra, rb = a[point], b[point]
        na, nb = dict(numbers(ra)), dict(numbers(rb))
        tol = ra.get("rate_tolerance_s_per_day") if isinstance(ra, dict) else None
        for key in na.keys() & nb.keys():
            if "wall_time" in key:  # the run's own speed, not a result
                continue
            x, y = na[key], nb[key]
            total += 1
            if x == y or (math.isnan(x) and math.isnan(y)):
                same += 1
                continue
            diff = abs(x - y)
            rel = diff / max(abs(x), abs(y))
            field = re.sub(r"\[\d+\]$", "", key.split(".")[-1])  # a column or list: its worst entry
            if field not in DIAGNOSTICS and diff > worst.get(field, (-1.0, 0.0))[0]:
                worst[field] = (diff, rel)
            if tol is not None and key.endswith("_s_per_day") and not key.startswith("rate_") and diff > tol:
                beyond.append((diff, key, tol))
    if a.keys() != b.keys():
        ok = False
        lines.append(f"  the two runs have different points ({len(a)} and {len(b)})")
    lines.insert(0, f"{stem}: no point results or time series to compare" if not total else
                 f"{stem}: {same} of {total} result values the same bits"
                 + ("" if same == total else "; the largest differences: " + ", ".join(
                     f"{f} {d:.3g} ({r:.2g} relative)" for f, (d, r) in sorted(worst.items(), key=lambda i: -i[1][1])[:4])))
    if beyond:
        diff, key, tol = max(beyond)
        lines.append(f"  {len(beyond)} rates move more than the shooting search's tolerance ({tol:.3g} s/day), "
                     f"the most {key} by {diff:.3g} s/day: the co-simulation's own error at this step "
                     f"(its tolerance is the scene's stated accuracy against the reference, not the search's)")
    ha, hb = (json.loads((out / side / "summary.json").read_text()).get("headlines", []) for side in SIDES)
    for x, y in zip(ha, hb):
        if (isinstance(x.get("ours"), (int, float)) and x.get("ours") != y.get("ours")
                and "wall time" not in x.get("quantity", "")):
            tol = x.get("tolerance")
            within = tol is None or abs(x["ours"] - y["ours"]) <= tol
            ok &= within
            lines.append(f"  headline {x['quantity']!r}: {x['ours']} -> {y['ours']} {x.get('unit', '')}"
                         + ("" if tol is None else f" (tolerance {tol}: {'within' if within else 'OUTSIDE'})"))
    return lines, ok


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True, type=Path, help="a folder for the runs (one per scene and side)")
    ap.add_argument("--only", nargs="+", metavar="STEM", help="these scenes (default: every scenes/*.toml)")
    ap.add_argument("--quick", action="store_true", help="scenarios/quick.json's reduced settings")
    args = ap.parse_args()
    stems = args.only or sorted(p.stem for p in SCENES.glob("*.toml"))
    missing = [s for s in stems if not (SCENES / f"{s}.toml").is_file()]
    if missing:
        ap.error(f"--only: no scene {', '.join(missing)} in {SCENES}")
    quick = json.loads((SCENES / "quick.json").read_text()) if args.quick else {}
    all_ok = True
    for stem in stems:
        failed = [why for side, value in SIDES.items()
                  if (why := run(stem, value, quick.get(stem, []), args.out / stem / side))]
        if failed:
            print(f"{stem}: not compared ({failed[0]})", flush=True)
            continue
        lines, ok = compare(stem, args.out / stem)
        all_ok &= ok
        print("\n".join(lines), flush=True)
    return 0 if all_ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
