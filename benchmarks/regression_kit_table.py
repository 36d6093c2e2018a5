"""The regression kit's table: which tool passes which case, at which step.

    PYTHONPATH=. python3 benchmarks/regression_kit_table.py --out out/regression-kit
    PYTHONPATH=. python3 benchmarks/regression_kit_table.py --calibrate --out out/regression-kit

Exports the suite (``clockwork export-suite``) into OUT/suite, runs every
case in clockwork's master (the scene's settings: event location on) and
in fmpy's SSP runner (``simulate_fmu`` for the single FMU), libcosim and
ecos (``python -m clockwork.kit.tools``, one subprocess per run) at the
case's output grid h and at h/10, grades every result with ``clockwork
compare`` and writes OUT/table.md (and OUT/table.json). The single-FMU
results at h also go into the suite's FMI Cross-Check results tree, which
``fmpy.cross_check.validate_vendor_repo`` then checks with its own tube.

--calibrate runs only clockwork: its own master with event location on
(the result as written, and only its rows on the output grid, as a tool
that writes the grid alone), without event location at h, and at a coarse
fixed step 5 h; prints each case's worst errors and the tolerances they
suggest (10 x the event-locating master's worst, rounded up to 1, 2 or 5
times a power of ten) and whether the others fail them.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from clockwork.kit.cases import CASES  # noqa: E402
from clockwork.kit.csvio import Result, read_result  # noqa: E402
from clockwork.kit.grade import grade, load_case  # noqa: E402
from clockwork.kit.runners import run_clockwork  # noqa: E402
from clockwork.kit.suite import case_dir, export_suite  # noqa: E402

TOOLS = ("fmpy", "libcosim", "ecos")


def _round_up(x: float) -> float:
    if x <= 0:
        return 0.0
    e = math.floor(math.log10(x))
    for m in (1, 2, 5, 10):
        if m * 10**e >= x * (1 - 1e-12):
            return float(m * 10**e)
    return float(10 ** (e + 1))


def _grid_only(res: Result, grid: float) -> Result:
    k = np.rint(res.time / grid)
    on = np.abs(res.time - k * grid) <= 1e-6 * grid
    return Result(res.source + " (grid rows)", res.time[on], {n: v[on] for n, v in res.columns.items()})


def _worst(g) -> dict:
    return {c.what.split(" (")[0]: c.worst for c in g.checks}


def calibrate(out: Path) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    report = {}
    for c in CASES.values():
        data = load_case(c.name)
        f = out / f"{c.name}.clockwork.csv"
        run_clockwork(c, f)
        full = grade(read_result(f), data)
        grid = grade(_grid_only(read_result(f), c.grid), data)
        worst = {k: max(v, _worst(grid)[k]) for k, v in _worst(full).items()}
        suggested = {k: _round_up(10 * max(v, 1e-10)) for k, v in worst.items()}
        rows = {"clockwork": _worst(full), "clockwork, grid rows": _worst(grid), "suggested": suggested}
        for label, kw in (("no event location, h", {"event_location": False}),
                          ("no event location, 5 h", {"event_location": False, "step": 5 * c.grid}),
                          ("event location, 5 h", {"step": 5 * c.grid})):
            g_path = out / f"{c.name}.{label.replace(' ', '_').replace(',', '')}.csv"
            run_clockwork(c, g_path, **kw)
            g = grade(read_result(g_path), data)
            rows[label] = {**_worst(g), "passed": g.passed}
        report[c.name] = rows
        print(f"{c.name}:")
        for label, r in rows.items():
            print(f"  {label:<24} " + "  ".join(f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}"
                                                  for k, v in r.items()))
    return report


def _run_tool(tool: str, cdir: Path, h: float, out: Path) -> tuple[Path | None, str, float]:
    # ecos unpacks every SSP into the temporary directory and leaves it there: give each run its own.
    scratch = tempfile.TemporaryDirectory(prefix="kit_tool.")
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""), TMPDIR=scratch.name)
    t0 = time.perf_counter()
    try:
        p = subprocess.run([sys.executable, "-m", "clockwork.kit.tools", tool, str(cdir), "--step", repr(h),
                            "--out", str(out)], capture_output=True, text=True, timeout=1800, env=env)
    except subprocess.TimeoutExpired:
        return None, "timeout", time.perf_counter() - t0
    finally:
        scratch.cleanup()
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        last = (p.stderr.strip().splitlines() or ["?"])[-1]
        return None, f"exit {p.returncode}: {last[:120]}", wall
    return out, "", wall


def _tool_version(tool: str) -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version({"fmpy": "fmpy", "libcosim": "libcosimpy", "ecos": "ecospy"}[tool])
    except PackageNotFoundError:
        return "unknown"


def cross_check_result(suite: Path, tool: str, c, result_path: Path, passed: bool) -> Path:
    """A single-FMU result in the FMI Cross-Check results tree of the suite:
    results/2.0/cs/linux64/<tool>/<version>/clockwork/<version>/<Model>/<Model>_out.csv
    (columns: time and the FMU's variable names), `passed` when compare passed."""
    from clockwork import __version__
    from clockwork.kit.csvio import write_csv

    res = read_result(result_path)
    cols = [(s, res.match(s)) for s in c.tube_signals]
    d = suite / "results" / "2.0" / "cs" / "linux64" / tool / _tool_version(tool) / "clockwork" / __version__ / c.name
    d.mkdir(parents=True, exist_ok=True)
    write_csv(d / f"{c.name}_out.csv", ["time"] + [s for s, _ in cols],
              np.column_stack([res.time] + [res.columns[m] for _, m in cols]))
    (d / "passed").unlink(missing_ok=True)
    if passed:
        (d / "passed").write_text("")
    return d


def _cell(g) -> str:
    if g is None:
        return "error"
    if g.passed:
        return "pass"
    failed = [c.what.split(" (")[0].replace("tube ", "").split(".")[-1] for c in g.checks if not c.ok]
    return "FAIL (" + ", ".join(failed or ["result"]) + ")"


def table(out: Path, factors: list[float]) -> dict:
    suite = out / "suite"
    export_suite(suite)
    runs = out / "runs"
    runs.mkdir(parents=True, exist_ok=True)
    rows = []
    for c in CASES.values():
        cdir = case_dir(suite, c)
        data = load_case(cdir)
        f = runs / f"{c.name}.clockwork.csv"
        t0 = time.perf_counter()
        run_clockwork(c, f)
        g = grade(read_result(f), data)
        rows.append({"case": c.name, "tool": "clockwork", "step": load_case_scene_step(c), "event_location": True,
                     "grade": g.as_dict(), "cell": _cell(g), "wall_s": time.perf_counter() - t0})
        print(f"{c.name:<18} clockwork          {rows[-1]['cell']}", flush=True)
        for tool in TOOLS:
            for fac in factors:
                h = c.grid * fac
                res = runs / f"{c.name}.{tool}.{h:g}.csv"
                path, err, wall = _run_tool(tool, cdir, h, res)
                g = grade(read_result(path), data) if path else None
                rows.append({"case": c.name, "tool": tool, "step": h, "event_location": False,
                             "grade": g.as_dict() if g else None, "cell": _cell(g) if g else f"error: {err}",
                             "wall_s": wall})
                if c.kind == "fmu" and fac == 1 and g is not None:
                    cross_check_result(suite, tool, c, path, g.passed)
                print(f"{c.name:<18} {tool:<9} h={h:<7g} {rows[-1]['cell']}", flush=True)
    from fmpy.cross_check.validate_vendor_repo import validate_repo

    fmus, results, problems = validate_repo(str(suite))
    print(f"validate_vendor_repo({suite}): {fmus} FMU(s), {results} result(s), {len(problems)} problem(s)")
    for p in problems:
        print(f"  {p}")
    return {"rows": rows, "cross_check": {"fmus": fmus, "results": results, "problems": problems}}


def load_case_scene_step(c) -> float:
    from clockwork.kit.cases import load_case_scene

    return load_case_scene(c).master.step


def markdown(result: dict, factors: list[float]) -> str:
    rows = result["rows"]
    cols = ["clockwork"] + [f"{t} h" if f == 1 else f"{t} {f:g} h" for t in TOOLS for f in factors]
    lines = ["| case (grid h) | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for c in CASES.values():
        cells = []
        mine = [r for r in rows if r["case"] == c.name]
        cw = next(r for r in mine if r["tool"] == "clockwork")
        cells.append(f"{cw['cell']} ({cw['step']:g} s, events located)")
        for t in TOOLS:
            for f in factors:
                r = next(r for r in mine if r["tool"] == t and abs(r["step"] - c.grid * f) < 1e-12)
                cells.append(r["cell"])
        lines.append(f"| {c.name} ({c.grid:g} s) | " + " | ".join(cells) + " |")
    lines += ["", "Worst errors (tube: largest |y - y_ref| on the grid; ticks, switches: largest "
              "|t - t_expected| in s):", "",
              "| case | tool | step (s) | " + " | ".join(["phi", "w", "a2", "ticks", "switches"]) + " | verdict |",
              "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        g = r["grade"]
        if g is None:
            lines.append(f"| {r['case']} | {r['tool']} | {r['step']:g} | - | - | - | - | - | {r['cell']} |")
            continue
        w = {c["what"].split(" (")[0].split(".")[-1].replace("tube ", ""): c["worst"] for c in g["checks"]}

        def f(k):
            v = w.get(k)
            return "-" if v is None else f"{v:.2g}"

        lines.append(f"| {r['case']} | {r['tool']} | {r['step']:g} | {f('phi')} | {f('w')} | {f('a2')} | "
                     f"{f('ticks')} | {f('switches')} | {'pass' if g['passed'] else 'FAIL'} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="out/regression-kit")
    p.add_argument("--calibrate", action="store_true")
    p.add_argument("--factors", default="1,0.1", help="tool steps as multiples of the case's output grid")
    a = p.parse_args(argv)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    if a.calibrate:
        rep = calibrate(out / "calibration")
        (out / "calibration.json").write_text(json.dumps(rep, indent=2, allow_nan=False) + "\n")
        return 0
    factors = [float(x) for x in a.factors.split(",")]
    res = table(out, factors)
    (out / "table.json").write_text(json.dumps(res, indent=2, allow_nan=False) + "\n")
    md = markdown(res, factors)
    xc = res["cross_check"]
    md += (f"\nThe single-FMU results at h, written into the suite's FMI Cross-Check results tree "
           f"(`results/2.0/cs/linux64/<tool>/<version>/clockwork/<version>/<Model>/`, `passed` where compare "
           f"passed): `fmpy.cross_check.validate_vendor_repo` finds {xc['fmus']} FMU(s), {xc['results']} "
           f"result(s), {len(xc['problems'])} problem(s).\n")
    (out / "table.md").write_text(md)
    print(md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
