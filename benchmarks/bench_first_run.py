"""The first run of a user's own FMU as a whole process: `clockwork run
model.fmu` (with its default plot, and with --no-plot) against `fmpy
simulate model.fmu`, on Reference-FMUs' BouncingBall (FMI 2.0 build of
modelica/Reference-FMUs; give its path, nothing here builds it).

The three commands run as fresh processes one after the other in triples
(fmpy, clockwork, clockwork --no-plot, fmpy, ...), each into a new output
directory; fmpy writes its result as CSV (--output-file), as clockwork
does, and draws nothing. Each triple's ratios are taken within it, so that
a machine whose speed drifts moves all three alike; the median ratio is the
figure to quote (docs/benchmarks.md, "The first run of an FMU"). One
triple first as a warm-up (file caches, the FMU's extraction into
clockwork's cache). Each clockwork run's PNG is checked complete (a PNG's
end chunk) when the command has returned.

    python benchmarks/bench_first_run.py BouncingBall.fmu --triples 7
    python benchmarks/bench_first_run.py BouncingBall.fmu --profile OUT   # cProfile and -X importtime of each command

Targets (issue 42): with the default plot <= 2.0x fmpy, --no-plot <= 0.9x.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

BIN = Path(sys.executable).parent


def timed(command: list[str], env: dict) -> float:
    """Wall time of a whole process, s (it must succeed)."""
    return timed_cpu(command, env)[0]


def timed_cpu(command: list[str], env: dict) -> tuple[float, float]:
    """(wall time, CPU time) of a whole process, s: the CPU time (user +
    system) of the command and every child it waited for (the plot process),
    which a busy machine stretches less than the wall time."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    r = subprocess.run(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed ({r.returncode}): {r.stderr.strip()}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def png_complete(folder: Path) -> bool:
    pngs = sorted(folder.glob("*.png"))
    return bool(pngs) and all(p.read_bytes().endswith(b"IEND\xaeB`\x82") for p in pngs)


def commands(fmu: Path, scratch: Path, k: int) -> dict[str, list[str]]:
    clockwork = [str(BIN / "clockwork"), "run", str(fmu), "--no-progress"]
    return {"fmpy": [str(BIN / "fmpy"), "simulate", str(fmu), "--output-file", str(scratch / f"fmpy{k}.csv")],
            "clockwork": clockwork + ["--out", str(scratch / f"plot{k}")],
            "no-plot": clockwork + ["--out", str(scratch / f"noplot{k}"), "--no-plot"]}


def profile(fmu: Path, env: dict, out: Path) -> None:
    """Each command once under cProfile (out/<name>.prof) and once with
    -X importtime (out/<name>.imports, the import lines sorted by cumulative
    time), after a warm-up run."""
    out.mkdir(parents=True, exist_ok=True)
    scratch = out / "runs"
    for name, command in commands(fmu, scratch, 0).items():
        scratch.mkdir(exist_ok=True)
        timed(command, env)
        shutil.rmtree(scratch)
        scratch.mkdir()
        # the console scripts are Python scripts: run by this interpreter under the profiler
        subprocess.run([sys.executable, "-m", "cProfile", "-o", str(out / f"{name}.prof"), *command],
                       env=env, stdout=subprocess.DEVNULL, check=True)
        shutil.rmtree(scratch)
        scratch.mkdir()
        r = subprocess.run([sys.executable, "-X", "importtime", *command], env=env, stdout=subprocess.DEVNULL,
                           stderr=subprocess.PIPE, text=True, check=True)
        lines = [ln for ln in r.stderr.splitlines() if ln.startswith("import time:") and "|" in ln]
        rows = []
        for ln in lines[1:]:  # the first is the header
            own, cum, module = ln[len("import time:"):].split("|")
            rows.append((int(cum), int(own), module.rstrip()))
        rows.sort(reverse=True)
        (out / f"{name}.imports").write_text("".join(f"{c / 1e3:8.1f} ms cum {o / 1e3:7.1f} ms own {m}\n"
                                                     for c, o, m in rows))
        shutil.rmtree(scratch)
    print(f"profiles in {out}: python -m pstats {out}/clockwork.prof; sort -rn {out}/clockwork.imports | head")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("fmu", type=Path, help="Reference-FMUs' BouncingBall.fmu (FMI 2.0)")
    ap.add_argument("--triples", type=int, default=7, help="counted triples (default 7)")
    ap.add_argument("--profile", type=Path, help="profile each command once into this folder instead")
    args = ap.parse_args()
    fmu = args.fmu.resolve()
    env = dict(os.environ, CLOCKWORK_CACHE=os.environ.get("CLOCKWORK_CACHE", str(Path.home() / ".cache/clockwork")),
               MPLBACKEND="Agg")
    if args.profile:
        profile(fmu, env, args.profile)
        return 0
    scratch = Path(tempfile.mkdtemp(prefix="first-run."))
    try:
        rows, cpu_rows = [], []
        for k in range(args.triples + 1):
            cmds = commands(fmu, scratch, k)
            measured = {name: timed_cpu(c, env) for name, c in cmds.items()}
            if not png_complete(scratch / f"plot{k}"):
                raise SystemExit(f"{scratch / f'plot{k}'}: a PNG is missing or incomplete when the command returned")
            if k:
                t = {name: m[0] for name, m in measured.items()}
                c = {name: m[1] for name, m in measured.items()}
                rows.append((t["fmpy"], t["clockwork"], t["no-plot"], t["clockwork"] / t["fmpy"],
                             t["no-plot"] / t["fmpy"]))
                cpu_rows.append((c["fmpy"], c["clockwork"], c["no-plot"], c["clockwork"] / c["fmpy"],
                                 c["no-plot"] / c["fmpy"]))
                print(f"triple {k}: fmpy {t['fmpy']:.3f} s, clockwork {t['clockwork']:.3f} s "
                      f"({rows[-1][3]:.2f}x), --no-plot {t['no-plot']:.3f} s ({rows[-1][4]:.2f}x); CPU "
                      f"{c['fmpy']:.3f}, {c['clockwork']:.3f} ({cpu_rows[-1][3]:.2f}x), {c['no-plot']:.3f} s "
                      f"({cpu_rows[-1][4]:.2f}x)", flush=True)
        for what, table in (("wall", rows), ("CPU", cpu_rows)):
            med = [statistics.median(x) for x in zip(*table)]
            print(f"{what}, median of {len(table)} triples: fmpy {med[0]:.3f} s; clockwork {med[1]:.3f} s, "
                  f"{med[3]:.2f}x (range {min(r[3] for r in table):.2f} to {max(r[3] for r in table):.2f}; "
                  f"target <= 2.0x); --no-plot {med[2]:.3f} s, {med[4]:.2f}x (range "
                  f"{min(r[4] for r in table):.2f} to {max(r[4] for r in table):.2f}; target <= 0.9x)")
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
