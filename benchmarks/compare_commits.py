"""Two builds of clockwork side by side: whole commands timed in alternating
pairs, the median of the per-pair ratios printed (new / old; below 1 is
faster).

The old side is a commit built beside the working tree: a `git worktree`
in a temporary folder, its own CMake build (Release, the FMUs and the
compiled core) and its own venv. The new side is the working tree as built
(`cmake --build build` first), or another commit (--new). Each venv holds
only a .pth file: the tree first, then this interpreter's site-packages,
so both sides import the same numpy, scipy, fmpy and matplotlib and run in
the same way, and differ only in clockwork itself. Every command runs as a
fresh process with the point cache off, into a new output folder; one
warm-up pair first (file caches). The temporary folder and the worktree
are removed at the end, also after an error or Ctrl-C.

    python benchmarks/compare_commits.py c438f17 --pairs 5
    python benchmarks/compare_commits.py e351520 --pairs 5 --bench fig4a hoyng hoyng_fmi3

Run it before every landing that touches the FMUs, the runtime or the
master (docs/benchmarks.md). A benchmark the old side cannot run (e.g.
the FMI 3.0 build before it existed) is reported and skipped.
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import site
import statistics
import subprocess
import sys
import sysconfig
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

HOYNG_PERIODS = 60_000


def benchmarks(hoyng_periods: int) -> dict[str, list[str]]:
    """name -> the clockwork arguments (the output folder is appended)."""
    stop = f"experiment.stop={hoyng_periods * 2 * math.pi!r} s"
    hoyng = ["run", "hoyng_fig6", "--no-progress", "--set", stop]
    return {
        "fig4a": ["run", "ziemkiewicz_fig4a", "--no-progress"],
        "hoyng": hoyng,
        "hoyng_fmi3": hoyng + ["--set", "master.fmi_version=3"],
    }


def git(*args: str, cwd: Path = ROOT) -> str:
    return subprocess.run(["git", *args], cwd=cwd, check=True, capture_output=True, text=True).stdout.strip()


def build(tree: Path, log: Path) -> None:
    """The FMUs and the compiled core of `tree`, Release, in tree/build."""
    with open(log, "w") as out:
        for cmd in (["cmake", "-S", str(tree), "-B", str(tree / "build"), "-DCMAKE_BUILD_TYPE=Release",
                     f"-DPython3_EXECUTABLE={sys.executable}"] + (["-G", "Ninja"] if shutil.which("ninja") else []),
                    ["cmake", "--build", str(tree / "build")]):
            if subprocess.run(cmd, stdout=out, stderr=subprocess.STDOUT).returncode != 0:
                raise SystemExit(f"compare_commits: building {tree} failed: see {log}")


def venv(folder: Path, tree: Path) -> Path:
    """A venv that imports clockwork from `tree` and the rest from this
    interpreter's site-packages; its python."""
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(folder)], check=True)
    purelib = Path(sysconfig.get_path("purelib", vars={"base": str(folder), "platbase": str(folder)}))
    # Plain path lines: the editable install's .pth in site-packages is not
    # run from here, so clockwork comes from `tree` alone.
    (purelib / "compare.pth").write_text("\n".join([str(tree), *site.getsitepackages()]) + "\n")
    return folder / "bin" / "python"


def timed(python: Path, args: list[str], cwd: Path, env: dict) -> tuple[float, str | None]:
    """(wall time s, None) of a whole process, or (nan, its last stderr line) when it fails."""
    t0 = time.perf_counter()
    r = subprocess.run([str(python), "-m", "clockwork", *args], cwd=cwd, env=env,
                       stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        lines = r.stderr.strip().splitlines() or [f"exit code {r.returncode}"]
        return math.nan, lines[-1]
    return wall, None


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("old", help="the earlier commit (any git revision)")
    ap.add_argument("--new", help="a commit for the new side (default: the working tree as built)")
    ap.add_argument("--pairs", type=int, default=5, help="counted pairs per benchmark (default 5)")
    ap.add_argument("--bench", nargs="+", default=["fig4a", "hoyng"], help="fig4a, hoyng, hoyng_fmi3")
    ap.add_argument("--hoyng-periods", type=int, default=HOYNG_PERIODS,
                    help=f"nominal periods of Hoyng's clock (default {HOYNG_PERIODS})")
    args = ap.parse_args()
    table = benchmarks(args.hoyng_periods)
    unknown = [b for b in args.bench if b not in table]
    if unknown:
        ap.error(f"--bench: unknown {', '.join(unknown)}; expected some of {', '.join(table)}")
    if args.pairs < 1:
        ap.error("--pairs: expected a whole number >= 1")
    scratch = Path(tempfile.mkdtemp(prefix="cw-compare."))
    trees: list[Path] = []
    try:
        sides = {}
        for name, rev in (("old", args.old), ("new", args.new)):
            if rev is None:
                if not (ROOT / "lib").is_dir():
                    raise SystemExit("compare_commits: the working tree has no build: run cmake --build build")
                tree, label = ROOT, "working tree"
            else:
                sha = git("rev-parse", "--verify", f"{rev}^{{commit}}")
                tree, label = scratch / name, f"{rev} ({sha[:9]})"
                git("worktree", "add", "--detach", str(tree), sha)
                trees.append(tree)
                print(f"building {label} in {tree} ...", flush=True)
                build(tree, scratch / f"{name}-build.log")
            # Bytecode made once, as tools/setup.sh and pip do: a tree without
            # it compiles its sources at every start (PYTHONDONTWRITEBYTECODE).
            subprocess.run([sys.executable, "-m", "compileall", "-q", str(tree / "clockwork")],
                           stdout=subprocess.DEVNULL, check=True)
            sides[name] = (venv(scratch / f"venv-{name}", tree), tree, label)
        print(f"old: {sides['old'][2]}\nnew: {sides['new'][2]}")
        env = dict(os.environ, CLOCKWORK_CACHE="off")
        env.pop("PYTHONPATH", None)
        for bench in args.bench:
            rows, failed = [], None
            for k in range(args.pairs + 1):
                times = {}
                for name in ("old", "new") if k % 2 else ("new", "old"):  # alternate which goes first
                    python, tree, _ = sides[name]
                    times[name], why = timed(python, table[bench] + ["--out", str(scratch / f"{bench}-{name}{k}")],
                                             tree, env)
                    if why:
                        failed = f"{name} side failed: {why}"
                        break
                if failed:
                    break
                if k:  # pair 0 warms the file caches
                    rows.append((times["old"], times["new"], times["new"] / times["old"]))
                    print(f"{bench} pair {k}: old {times['old']:.3f} s, new {times['new']:.3f} s, "
                          f"new/old {rows[-1][2]:.3f}", flush=True)
            if failed:
                print(f"{bench}: skipped ({failed})", flush=True)
                continue
            med = [statistics.median(x) for x in zip(*rows)]
            print(f"{bench}: median of {len(rows)} pairs: old {med[0]:.3f} s, new {med[1]:.3f} s, "
                  f"new/old {med[2]:.3f} (range {min(r[2] for r in rows):.3f} to {max(r[2] for r in rows):.3f})",
                  flush=True)
    except KeyboardInterrupt:
        print("compare_commits: interrupted", file=sys.stderr)
        return 130
    finally:
        for tree in trees:
            subprocess.run(["git", "worktree", "remove", "--force", str(tree)], cwd=ROOT, capture_output=True)
        shutil.rmtree(scratch, ignore_errors=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
