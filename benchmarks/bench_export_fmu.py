"""The exported system FMU (clockwork export-fmu) against clockwork itself.

1. Whole process, in pairs: `clockwork run SCENE` (point cache off, a new
   output directory; it also writes the CSV and the plots) against a fresh
   Python that runs the exported FMU with fmpy's simulate_fmu at the
   scene's step as output interval. The median ratio fmpy / clockwork.
2. The front's cost per communication step, in one process: the exported
   FMU stepped over the whole run by one fmi2DoStep (the master's own
   steps, no importer between them) against the compiled master's
   run_until over the same scene (engine/compiled.py); the difference over
   the number of steps is what the front adds per step. And the same FMU
   stepped by one fmi2DoStep per communication step, which adds fmpy's
   ctypes call per step.

    python benchmarks/bench_export_fmu.py --pairs 5
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

FMPY_RUN = "from fmpy import simulate_fmu; import sys; simulate_fmu(sys.argv[1], output_interval=float(sys.argv[2]))"


def timed(command: list[str], env: dict) -> float:
    began = time.perf_counter()
    subprocess.run(command, check=True, env=env, stdout=subprocess.DEVNULL)
    return time.perf_counter() - began


def in_process(fmu: Path, scene_spec: str) -> dict:
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    from clockwork.analyses.context import build_system
    from clockwork.run.catalog import load_scene

    scene = load_scene(scene_spec)
    start, stop, step = scene.experiment.start, scene.experiment.stop, scene.master.step
    n = round((stop - start) / step)
    best = {}
    for _ in range(3):
        system = build_system(scene)
        with system:
            t0 = time.perf_counter()
            system.master.run_until(stop)
            best["master"] = min(best.get("master", 1e9), time.perf_counter() - t0)
            steps = system.master.stats.steps
        md = read_model_description(str(fmu))
        unzip = extract(str(fmu))
        for mode in ("one", "each"):
            slave = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier,
                              instanceName="x")
            slave.instantiate()
            slave.setupExperiment(startTime=start)
            slave.enterInitializationMode()
            slave.exitInitializationMode()
            t0 = time.perf_counter()
            if mode == "one":
                slave.doStep(start, stop - start)
            else:
                t = start
                for k in range(1, n + 1):
                    nxt = start + k * step
                    slave.doStep(t, nxt - t)
                    t = nxt
            best[mode] = min(best.get(mode, 1e9), time.perf_counter() - t0)
            slave.terminate()
            slave.freeInstance()
    return {"steps": steps, "communication_points": n, **best}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="core_grasshopper")
    ap.add_argument("--pairs", type=int, default=5)
    args = ap.parse_args()
    env = dict(os.environ, CLOCKWORK_CACHE="off")
    with tempfile.TemporaryDirectory() as tmp:
        fmu = Path(tmp) / "system.fmu"
        subprocess.run([sys.executable, "-m", "clockwork", "export-fmu", args.scene, "--out", str(fmu)], check=True,
                       stdout=subprocess.DEVNULL)
        from clockwork.run.catalog import load_scene

        step = load_scene(args.scene).master.step
        ratios = []
        for i in range(args.pairs + 1):
            ours = timed([sys.executable, "-m", "clockwork", "run", args.scene, "--out", f"{tmp}/run{i}"], env)
            theirs = timed([sys.executable, "-c", FMPY_RUN, str(fmu), repr(step)], env)
            if i:  # the first pair warms the file caches
                ratios.append(theirs / ours)
                print(f"pair {i}: clockwork run {ours:.3f} s, exported FMU in fmpy {theirs:.3f} s, "
                      f"ratio {theirs / ours:.2f}")
        print(f"median ratio (fmpy with the exported FMU / clockwork run): {statistics.median(ratios):.2f}")
        r = in_process(fmu, args.scene)
        steps = r["steps"]
        print(f"in process, {steps} master steps, {r['communication_points']} communication points (best of 3):")
        print(f"  compiled master run_until: {r['master'] * 1e3:.2f} ms")
        print(f"  exported FMU, one fmi2DoStep: {r['one'] * 1e3:.2f} ms "
              f"(the front adds {(r['one'] - r['master']) / steps * 1e6:+.3f} us per step)")
        print(f"  exported FMU, one fmi2DoStep per point (fmpy's ctypes call each): {r['each'] * 1e3:.2f} ms "
              f"({(r['each'] - r['master']) / r['communication_points'] * 1e6:+.3f} us per point)")


if __name__ == "__main__":
    main()
