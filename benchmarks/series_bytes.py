"""The bytes of timeseries.csv for a few bundled scenes and FMUs, on both
engines: run once with the code before a change and once after, and
compare the digests (the streamed writer must give the whole-run writer's
bytes).

    python benchmarks/series_bytes.py OUT_DIR [CLOCKWORK_EXECUTABLE]

prints "<case> <engine> <sha256 of timeseries.csv>" per case. Give both runs
the same FMUs (CLOCKWORK_FMU_DIR for the scenes' and Pendulum.fmu,
CW_TEST_FMU_DIR for the test FMUs): FMUs built from other sources give
other numbers.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TEST_FMUS = Path(os.environ.get("CW_TEST_FMU_DIR", ROOT / "build" / "test-fmus"))

CASES = {
    "core_grasshopper": ["core_grasshopper"],
    "core_grasshopper_drag": ["core_grasshopper_drag"],
    "core_vibration": ["core_vibration"],
    "core_vibration_every_step": ["core_vibration", "--set", "experiment.stop=20", "--set", "master.step=0.001"],
    "Pendulum.fmu": [str(Path(os.environ.get("CLOCKWORK_FMU_DIR", ROOT / "fmus")) / "Pendulum.fmu")],
    "TestTypes.fmu": [str(TEST_FMUS / "TestTypes.fmu")],
    "TestStair.fmu": [str(TEST_FMUS / "TestStair.fmu")],
    "fmi3/TestDecay.fmu": [str(TEST_FMUS / "fmi3" / "TestDecay.fmu")],
    "fmi3/MeBall.fmu": [str(TEST_FMUS / "fmi3" / "MeBall.fmu")],
}


def main() -> int:
    out = Path(sys.argv[1])
    exe = sys.argv[2] if len(sys.argv) > 2 else "clockwork"
    for name, args in CASES.items():
        for engine in ("compiled", "python"):
            d = out / f"{name.replace('/', '_')}.{engine}"
            r = subprocess.run([exe, "run", *args, "--out", str(d), "--no-plot", "--no-progress",
                                "--set", f"master.engine={engine}"], capture_output=True, text=True)
            f = d / "timeseries.csv"
            digest = hashlib.sha256(f.read_bytes()).hexdigest() if f.exists() else f"none (exit {r.returncode})"
            print(f"{name} {engine} {digest}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
