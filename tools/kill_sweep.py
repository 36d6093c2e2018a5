"""Kill a sweep again and again, then check that the finished result is the
uninterrupted one, byte for byte, with no orphan process and no .part file.

    python tools/kill_sweep.py --kills 20 [--scene ziemkiewicz_fig4a] [--workers 2] [--seed 1]

An uninterrupted run into a directory of its own comes first, and its wall
time sets the scale. Then each round starts `clockwork run SCENE` (a bundled
scene's name or a file) into one shared directory and SIGKILLs it at a
random moment between 5 % and 95 % of that time; the last round runs to the
end. It prints how many kills landed before the run finished on its own;
docs/reliability.md quotes what it prints.
"""

from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

def descendants(pid: int) -> set[int]:
    found, todo = set(), [pid]
    while todo:
        for task in Path(f"/proc/{todo.pop()}/task").glob("*"):
            try:
                kids = {int(k) for k in (task / "children").read_text().split()}
            except OSError:
                continue
            todo += list(kids - found)
            found |= kids
    return found


def running(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kills", type=int, default=20)
    ap.add_argument("--scene", default="ziemkiewicz_fig4a")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    rng = random.Random(args.seed)
    with tempfile.TemporaryDirectory(prefix="kill_sweep.") as tmp:
        tmp = Path(tmp)
        env = dict(os.environ, CLOCKWORK_CACHE="off", PYTHONPATH=str(ROOT))
        cmd = [sys.executable, "-m", "clockwork", "run", args.scene, "--no-progress", "--workers", str(args.workers)]
        clean = tmp / "clean"
        t0 = time.monotonic()
        c = subprocess.run(cmd + ["--out", str(clean)], env=env, capture_output=True, text=True)
        duration = time.monotonic() - t0
        orphans = landed = 0
        out = tmp / "killed"
        for k in range(args.kills):
            proc = subprocess.Popen(cmd + ["--out", str(out)], env=env, stdout=subprocess.DEVNULL,
                                    stderr=subprocess.DEVNULL)
            kids: set[int] = set()
            end = time.monotonic() + rng.uniform(0.05, 0.95) * duration
            while time.monotonic() < end and proc.poll() is None:
                kids |= descendants(proc.pid)
                time.sleep(0.01)
            if proc.poll() is None:
                proc.send_signal(signal.SIGKILL)
                landed += 1
            proc.wait()
            deadline = time.monotonic() + 10
            while any(running(p) for p in kids) and time.monotonic() < deadline:
                time.sleep(0.05)
            orphans += sum(running(p) for p in kids)
        r = subprocess.run(cmd + ["--out", str(out)], env=env, capture_output=True, text=True)
        same = r.returncode == c.returncode == 0 and (
            (out / "sweep.csv").read_bytes() == (clean / "sweep.csv").read_bytes())
        parts = sorted(str(p.relative_to(out)) for p in out.rglob("*.part"))
        print(f"uninterrupted run: {duration:.2f} s; "
              f"kills: {landed} of {args.kills} runs (the others finished first); orphan processes: {orphans}; "
              f".part files left: {len(parts)}; "
              f"sweep.csv byte-identical to an uninterrupted run: {'yes' if same else 'NO'}")
        if not same:
            print(r.stderr, c.stderr, file=sys.stderr)
        return 0 if same and not orphans and not parts else 1


if __name__ == "__main__":
    sys.exit(main())
