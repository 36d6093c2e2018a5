"""Every bundled scene on the FMI 2.0 and the FMI 3.0 build of the FMUs:
do they agree? (a benchmark, not a test: it runs every scene twice)

Each scene of scenarios/ runs through the ordinary runner (with the
gallery's quick overrides unless --full) once with master.fmi_version = 2
and once with 3, cache off. Then every number of the two summary.json
files (settings, wall times, digests and versions left out) and every
column of their CSV files are compared: times of events (tick columns,
*_time, *_s fields of ticks) against 1e-10 s, everything else against
1e-12, absolute or relative to the value, whichever is larger. Prints one
row per scene and the largest differences.

    python benchmarks/fmi3_agreement.py [--full] [--no-early-return] [--only STEM ...] [--out DIR]
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

os.environ["CLOCKWORK_CACHE"] = "off"

from clockwork.errors import ClockworkError  # noqa: E402
from clockwork.paths import scenarios_dir  # noqa: E402
from clockwork.run.catalog import load_scene  # noqa: E402
from clockwork.run.gallery import quick_overrides  # noqa: E402
from clockwork.run.scene_run import run_scene  # noqa: E402

SKIP_KEYS = {"settings", "wall_time_s", "wall_s", "sha256", "fmus", "version", "tool", "generated_by",
             "timing", "elapsed_s", "overrides", "scene_sha256", "statistics",
             "headlines"}  # the headlines repeat results beside the papers, and some are speeds


def _is_event_key(key: str) -> bool:
    k = key.lower()
    return "tick" in k or k.endswith("_time") or k.endswith("switch") or "event" in k


def walk(a, b, path, out):
    """Append (path, |a - b|, tolerance kind) for every number in both."""
    if isinstance(a, dict) and isinstance(b, dict):
        for k in a.keys() & b.keys():
            # Wall times, rates of work and iteration counts are not results.
            if (k not in SKIP_KEYS and "wall" not in k and "cpu_time" not in k and not k.endswith("per_s")
                    and "iterations" not in k):
                walk(a[k], b[k], f"{path}.{k}", out)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out.append((path + " (length)", math.inf, "value"))
        for i, (x, y) in enumerate(zip(a, b)):
            walk(x, y, f"{path}[{i}]", out)
    elif isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        d = abs(a - b) if (math.isfinite(a) and math.isfinite(b)) else (0.0 if a == b or (a != a and b != b) else math.inf)
        scale = max(1.0, abs(a))
        out.append((path, d / scale, "event" if _is_event_key(path.rsplit(".", 1)[-1]) else "value"))


def compare_csv(fa: Path, fb: Path, out):
    ra = list(csv.reader(fa.open()))
    rb = list(csv.reader(fb.open()))
    if len(ra) != len(rb) or ra[0] != rb[0]:
        out.append((f"{fa.name} (shape {len(ra)} vs {len(rb)} rows)", math.inf, "value"))
        return
    head = ra[0]
    for j, name in enumerate(head):
        worst = 0.0
        for x, y in zip(ra[1:], rb[1:]):
            try:
                u, v = float(x[j]), float(y[j])
            except (ValueError, IndexError):
                if x[j:j + 1] != y[j:j + 1]:
                    worst = math.inf
                continue
            if u == v or (u != u and v != v):
                continue
            worst = max(worst, abs(u - v) / max(1.0, abs(u)))
        if "iterations" in name or "wall" in name:
            continue  # not results
        kind = "event" if (name == "time" or _is_event_key(name) or fa.name == "ticks.csv") else "value"
        out.append((f"{fa.name}:{name}", worst, kind))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="full-size scenes (default: the gallery's quick overrides)")
    ap.add_argument("--only", nargs="+", default=None)
    ap.add_argument("--out", default=None, help="keep the runs here (default: a temporary folder)")
    ap.add_argument("--no-early-return", action="store_true",
                    help="run the FMI 3.0 build with master.early_return = false")
    a = ap.parse_args()
    sdir = scenarios_dir()
    quick = {} if a.full else quick_overrides(sdir)
    root = Path(a.out) if a.out else Path(tempfile.mkdtemp(prefix="fmi3-agreement-"))
    stems = a.only or sorted(p.stem for p in sdir.glob("*.toml"))
    print("| scene | FMI 2 s | FMI 3 s | largest value difference | largest event-time difference | agree |")
    print("|---|---|---|---|---|---|")
    failed = 0
    for stem in stems:
        walls = []
        try:
            for v in (2, 3):
                extra = ["master.early_return=false"] if a.no_early_return and v == 3 else []
                scene = load_scene(sdir / f"{stem}.toml",
                                   list(quick.get(stem, [])) + [f"master.fmi_version={v}"] + extra)
                t0 = time.perf_counter()
                run_scene(scene, root / f"fmi{v}" / stem, workers=1, progress=False)
                walls.append(time.perf_counter() - t0)
        except ClockworkError as e:
            failed += 1
            print(f"| {stem} | {walls[0] if walls else 0:.2f} | - | refused on FMI {len(walls) + 2}: "
                  f"{str(e).split(': ', 1)[-1]} | - | NO |", flush=True)
            continue
        d2, d3 = root / "fmi2" / stem, root / "fmi3" / stem
        diffs: list = []
        walk(json.loads((d2 / "summary.json").read_text()), json.loads((d3 / "summary.json").read_text()),
             "summary", diffs)
        for f in sorted(d2.glob("*.csv")):
            compare_csv(f, d3 / f.name, diffs)
        worst_v = max(((d, p) for p, d, k in diffs if k == "value"), default=(0.0, "-"))
        worst_e = max(((d, p) for p, d, k in diffs if k == "event"), default=(0.0, "-"))
        ok = worst_v[0] <= 1e-12 and worst_e[0] <= 1e-10
        failed += not ok
        print(f"| {stem} | {walls[0]:.2f} | {walls[1]:.2f} | {worst_v[0]:.1e} ({worst_v[1]}) | "
              f"{worst_e[0]:.1e} ({worst_e[1]}) | {'yes' if ok else 'NO'} |", flush=True)
    print(f"\n{len(stems) - failed} of {len(stems)} scenes agree (runs in {root})")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
