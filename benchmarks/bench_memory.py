"""Peak memory of a long recording against a one-minute run of the same scene.

A single run's series is written to disk as the run goes (results/series.py):
its peak memory should not grow with the run's length. Two scenes, each run
for one simulated minute and for its long span, recording as the issue asks:

- Hoyng's clock (hoyng_fig6's Pendulum and GrasshopperEscapement, noise
  included) over the scene's whole span, 3.0e7 s (4.8e6 nominal periods), a
  row at every tick: record.interval = master.step = the nominal period
  (2 pi s), pendulum.phi, pendulum.w, escapement.tau;
- the chaotic clock (ziemkiewicz_fig8b's pendulum, escapement and vibrating
  mechanism, Eq. 7) for an hour, a row every millisecond (its master step):
  pendulum.phi, pendulum.w, vibration.a2, vibration.a2dot.

Each run is `clockwork run SCENE --out DIR --no-plot --no-progress` (the
scene has no plots) in a child of a fresh Python process, whose
getrusage(RUSAGE_CHILDREN).ru_maxrss is the child's peak resident set.

    python benchmarks/bench_memory.py [--formats csv,parquet,mat] [--only hoyng|chaos] [--short]

prints a Markdown table (--short: 10x shorter long runs, for a try). Run by
another checkout's Python (`/path/to/other/.venv/bin/python
benchmarks/bench_memory.py`), it measures that checkout's clockwork.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SCENES = ROOT / "scenarios"


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(type(v))


def _scene(source: str, keep: list[str], master: dict, stop: float, record: dict) -> str:
    raw = tomllib.loads((SCENES / f"{source}.toml").read_text())
    lines = ["connections = " + _value([c for c in raw["connections"]
                                        if all(p.split(".")[0] in keep for p in c.split(" -> "))]),
             "", "[scene]", f'title = "{source}: a long recording (benchmarks/bench_memory.py)"']
    for name in keep:
        c = raw["components"][name]
        lines += ["", f"[components.{name}]"] + [f"{k} = {_value(v)}" for k, v in c.items()]
    lines += ["", "[experiment]", "start = 0.0", f"stop = {stop!r}"]
    lines += ["", "[master]"] + [f"{k} = {_value(v)}" for k, v in {**raw["master"], **master}.items()]
    lines += ["", "[record]"] + [f"{k} = {_value(v)}" for k, v in record.items()]
    lines += ["", "[analysis]", 'kind = "time_series"', ""]
    return "\n".join(lines)


def hoyng(stop: float) -> str:
    period = 6.283185307179586
    return _scene("hoyng_fig6", ["pendulum", "escapement"], {}, stop,
                  {"outputs": ["pendulum.phi", "pendulum.w", "escapement.tau"], "interval": period})


def chaos(stop: float) -> str:
    return _scene("ziemkiewicz_fig8b", ["pendulum", "escapement", "vibration"], {}, stop,
                  {"outputs": ["pendulum.phi", "pendulum.w", "vibration.a2", "vibration.a2dot"]})


_MEASURE = ("import resource, subprocess, sys, time\n"
            "t = time.perf_counter()\n"
            "r = subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)\n"
            "t = time.perf_counter() - t\n"
            "print(r.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, t, repr(r.stderr[-300:]))\n")


def measure(scene_text: str, folder: Path, formats: str) -> dict:
    scene = folder / "scene.toml"
    scene.write_text(scene_text)
    out = folder / "out"
    shutil.rmtree(out, ignore_errors=True)
    cmd = [sys.executable, "-c", _MEASURE, sys.executable, "-m", "clockwork", "run", str(scene), "--out", str(out),
           "--no-plot", "--no-progress", *(["--format", formats] if formats != "csv" else [])]  # older code: csv only
    rc, kb, wall, err = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout.split(" ", 3)
    if rc != "0":
        raise SystemExit(f"{scene}: exit {rc}: {err}")
    sizes = {p.name: p.stat().st_size for p in out.iterdir() if p.name.startswith("timeseries")}
    with open(out / "timeseries.csv" if "timeseries.csv" in sizes else scene) as f:
        rows = sum(1 for _ in f) - 1 if "timeseries.csv" in sizes else None
    shutil.rmtree(out, ignore_errors=True)
    return {"peak_mb": int(kb) / 1024, "wall_s": float(wall), "rows": rows, "bytes": sum(sizes.values())}


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--formats", default="csv")
    ap.add_argument("--only", choices=["hoyng", "chaos"], default=None)
    ap.add_argument("--short", action="store_true")
    args = ap.parse_args()
    cases = {"hoyng": (hoyng, 30159289.47446201, "Hoyng's clock, 3.0e7 s (4.8e6 periods), a row per tick"),
             "chaos": (chaos, 3600.0, "chaotic clock (Eq. 7), 1 hour, a row per ms")}
    print(f"formats: {args.formats}; {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}", flush=True)
    print("| scene | span | rows | files | wall | peak RSS | ratio to 1 minute |")
    print("|---|---|---|---|---|---|---|", flush=True)
    with tempfile.TemporaryDirectory(prefix="bench_memory.") as tmp:
        for key, (make, stop, label) in cases.items():
            if args.only and key != args.only:
                continue
            if args.short:
                stop /= 10
            short = measure(make(60.0), Path(tmp), args.formats)
            long = measure(make(stop), Path(tmp), args.formats)
            for span, m in (("60 s", short), (f"{stop:.3g} s", long)):
                ratio = f"{m['peak_mb'] / short['peak_mb']:.3f}"
                print(f"| {label} | {span} | {m['rows']} | {m['bytes'] / 1e6:.1f} MB | {m['wall_s']:.1f} s | "
                      f"{m['peak_mb']:.1f} MB | {ratio} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
