"""Systems of many FMUs beside the peers: whole-process time, the marginal
cost per FMU-step, peak memory and the agreement of the results.

    python benchmarks/bench_scale.py --fmus /work/thirdparty/rfmu/fmi2 --sizes 50 500 --rounds 3
    python benchmarks/bench_scale.py --sizes 10 100            # the project's stand-ins, anywhere

Two systems of N FMI 2.0 Co-Simulation FMUs, 1000 communication steps of
1e-3 s:

- ``chain``: a source (Reference-FMUs' VanDerPol, output x0) feeding N - 1
  feedthrough instances in a row (Feedthrough, Float64_continuous_input ->
  Float64_continuous_output); the last one's output is recorded;
- ``wide``: N - 1 independent sources (VanDerPol) into one sink with N - 1
  inputs (the project's test FMU TestSink, which integrates their sum; built
  into build/test-fmus), whose output is recorded.

Without --fmus the sources and the feedthroughs are the project's own test
FMUs (TestDecay, TestSum from build/test-fmus), so that a reduced form runs
wherever the project builds; with --fmus DIR they are DIR/VanDerPol.fmu
and DIR/Feedthrough.fmu (modelica/Reference-FMUs, FMI 2.0 build).

Each system is written twice into --work: an SSP 1.0 SSD
(SystemStructure.ssd beside the FMUs, only the connected Real connectors,
which every tool reads) and a scene file. The tools, each a fresh process
per run, rounds rotated:

- clockwork: `clockwork run` on the scene file (on the SSD it would also
  draw the recorded output), compiled engine, one thread
  (``clockwork-threads``: ``master.threads = 2``; ``clockwork-python``: the
  Python engine);
- libcosim (libcosimpy) and ecos (ecospy) on the same SSD, when installed;
- ``fmpy``: a hand-written Gauss-Seidel loop over fmpy's FMU2Slave objects.

Reported per system, tool and N: the median whole-process time over the
rounds, its growth exponent between the smallest and the largest N, the
marginal cost in microseconds per FMU-step (the slope between the two
largest N divided by 1000 steps), the peak resident memory (the child's
ru_maxrss) and the recorded output's largest difference from clockwork's
(and at which lag along the time axis it vanishes: a peer that passes
values on with a delay of one step per FMU agrees with clockwork's
Gauss-Seidel result shifted by that many steps).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

STEPS = 1000
STEP_S = 1e-3
REPO = Path(__file__).resolve().parent.parent

SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"


# -- the systems ---------------------------------------------------------------------------------


def _models(fmus: Path | None) -> dict:
    """The FMU files and variable names of the source, the feedthrough and the sink."""
    test = Path(os.environ.get("CW_TEST_FMU_DIR", REPO / "build" / "test-fmus"))
    if fmus is None:
        return {"source": (test / "TestDecay.fmu", "x"), "through": (test / "TestSum.fmu", "u1", "y"),
                "sink": (test / "TestSink.fmu", "u", "y")}
    return {"source": (fmus / "VanDerPol.fmu", "x0"),
            "through": (fmus / "Feedthrough.fmu", "Float64_continuous_input", "Float64_continuous_output"),
            "sink": (test / "TestSink.fmu", "u", "y")}


def system(kind: str, n: int, models: dict) -> tuple[list[tuple[str, Path]], list[tuple[str, str, str, str]], str]:
    """(components (name, FMU), connections (src, output, dst, input), recorded "instance.variable")."""
    src_fmu, src_out = models["source"]
    if kind == "chain":
        thr_fmu, thr_in, thr_out = models["through"]
        comps = [("v", src_fmu)] + [(f"f{i}", thr_fmu) for i in range(1, n)]
        conns = [("v" if i == 1 else f"f{i - 1}", src_out if i == 1 else thr_out, f"f{i}", thr_in)
                 for i in range(1, n)]
        return comps, conns, f"f{n - 1}.{thr_out}" if n > 1 else f"v.{src_out}"
    sink_fmu, sink_in, sink_out = models["sink"]
    comps = [(f"s{i}", src_fmu) for i in range(1, n)] + [("sink", sink_fmu)]
    conns = [(f"s{i}", src_out, "sink", f"{sink_in}[{i}]") for i in range(1, n)]
    return comps, conns, f"sink.{sink_out}"


def write_system(folder: Path, kind: str, n: int, models: dict) -> str:
    """SystemStructure.ssd (SSP 1.0) and scene.toml in `folder`, the FMUs
    copied beside them once each; returns the recorded variable."""
    comps, conns, recorded = system(kind, n, models)
    folder.mkdir(parents=True, exist_ok=True)
    files = {}
    for _, fmu in comps:
        if fmu not in files:
            files[fmu] = f"{fmu.stem}.fmu"
            shutil.copyfile(fmu, folder / files[fmu])
    inputs: dict[str, list[str]] = {}
    outputs: dict[str, list[str]] = {}
    for a, out, b, inp in conns:
        outputs.setdefault(a, []).append(out) if out not in outputs.get(a, []) else None
        inputs.setdefault(b, []).append(inp)
    rec_inst, rec_var = recorded.split(".", 1)
    if rec_var not in outputs.get(rec_inst, []):
        outputs.setdefault(rec_inst, []).append(rec_var)
    lines = ['<?xml version="1.0" encoding="UTF-8"?>',
             f'<ssd:SystemStructureDescription xmlns:ssd="{SSD}" xmlns:ssc="{SSC}" version="1.0" name="{kind}{n}">',
             '  <ssd:System name="root">', '    <ssd:Elements>']
    for name, fmu in comps:
        lines.append(f'      <ssd:Component name="{name}" type="application/x-fmu-sharedlibrary" '
                     f'source="{files[fmu]}">')
        lines.append('        <ssd:Connectors>')
        for kind_, names in (("input", inputs.get(name, [])), ("output", outputs.get(name, []))):
            for v in names:
                lines.append(f'          <ssd:Connector name="{v}" kind="{kind_}"><ssc:Real/></ssd:Connector>')
        lines.append('        </ssd:Connectors>')
        lines.append('      </ssd:Component>')
    lines.append('    </ssd:Elements>')
    lines.append('    <ssd:Connections>')
    for a, out, b, inp in conns:
        lines.append(f'      <ssd:Connection startElement="{a}" startConnector="{out}" endElement="{b}" '
                     f'endConnector="{inp}"/>')
    lines += ['    </ssd:Connections>', '  </ssd:System>',
              f'  <ssd:DefaultExperiment startTime="0.0" stopTime="{STEPS * STEP_S!r}"/>',
              '</ssd:SystemStructureDescription>', '']
    (folder / "SystemStructure.ssd").write_text("\n".join(lines))
    toml = ["[scene]", f'title = "{kind} of {n} FMUs"', "[experiment]", f"stop = {STEPS * STEP_S!r}",
            "[master]", f"step = {STEP_S!r}", "[record]", f'outputs = ["{recorded}"]']
    for name, fmu in comps:
        toml += [f"[components.{name}]", f'fmu = "{files[fmu]}"']
    toml.insert(0, "connections = [" + ", ".join(f'"{a}.{o} -> {b}.{i}"' for a, o, b, i in conns) + "]")
    (folder / "scene.toml").write_text("\n".join(toml) + "\n")
    return recorded


# -- one run in a child process --------------------------------------------------------------------


def run_libcosim(folder: Path, recorded: str) -> list[float]:
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.WARNING)
    inst, var = recorded.split(".", 1)
    ex = CosimExecution.from_ssp_file(str(folder / "SystemStructure.ssd"), step_size=round(STEP_S * 1e9))
    idx = ex.slave_index_from_instance_name(inst)
    ref = next(v.reference for v in ex.slave_variables(idx)
               if (v.name.decode() if isinstance(v.name, bytes) else v.name) == var)
    obs = CosimObserver.create_last_value()
    ex.add_observer(obs)
    values = []
    for _ in range(STEPS):
        if not ex.step():
            raise SystemExit("libcosim: a step failed")
        values.append(obs.last_real_values(idx, [ref])[0])
    return values


def run_ecos(folder: Path, recorded: str) -> list[float]:
    from ecospy import EcosLib, EcosSimulation

    EcosLib.set_log_level("warn")
    sim = EcosSimulation(step_size=STEP_S, ssp_path=str(folder))
    sim.init()
    ident = recorded.replace(".", "::", 1)
    values = []
    for _ in range(STEPS):
        sim.step()
        values.append(sim.get_real(ident))
    sim.terminate()
    return values


def run_fmpy(folder: Path, recorded: str) -> list[float]:
    """Gauss-Seidel by hand: each instance steps, then its outputs go to the
    inputs they feed (the feedthroughs and the sink see the newest values)."""
    import xml.etree.ElementTree as ET
    from ctypes import c_double, c_uint

    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    root = ET.parse(folder / "SystemStructure.ssd").getroot()
    q = f"{{{SSD}}}"
    slaves, mds = {}, {}
    unzipped = {}
    for c in root.iter(q + "Component"):
        src = folder / c.get("source")
        if src not in unzipped:
            unzipped[src] = (extract(str(src)), read_model_description(str(src)))
        unzip, md = unzipped[src]
        s = FMU2Slave(guid=md.guid, unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier,
                      instanceName=c.get("name"))
        s.instantiate()
        # the DefaultExperiment's tolerance, as clockwork passes it (TestDecay's steps depend on it)
        tol = md.defaultExperiment.tolerance if md.defaultExperiment is not None else None
        s.setupExperiment(tolerance=float(tol) if tol else None, startTime=0.0)
        s.enterInitializationMode()
        s.exitInitializationMode()
        slaves[c.get("name")] = s
        mds[c.get("name")] = {v.name: v.valueReference for v in md.modelVariables}
    links = [(c.get("startElement"), c.get("startConnector"), c.get("endElement"), c.get("endConnector"))
             for c in root.iter(q + "Connection")]
    feeds: dict[str, list] = {}
    for a, out, b, inp in links:
        feeds.setdefault(a, []).append(((c_uint * 1)(mds[a][out]), slaves[b], (c_uint * 1)(mds[b][inp])))
    order = list(slaves)  # sources and the chain in its order, the sink last
    inst, var = recorded.split(".", 1)
    rec = slaves[inst]
    rec_vr = (c_uint * 1)(mds[inst][var])
    value = (c_double * 1)()
    # The chain's feedthroughs compute their output from the input just set:
    # stepping v first, then each feedthrough after its input is set, is the
    # exact Gauss-Seidel order.
    values = []
    for k in range(STEPS):
        # clockwork's grid: the points are k h, each step the difference of two
        t, t_next = k * STEP_S, (k + 1) * STEP_S
        for name in order:
            s = slaves[name]
            s.fmi2DoStep(s.component, t, t_next - t, 1)
            for vr, dst, dvr in feeds.get(name, ()):
                s.fmi2GetReal(s.component, vr, 1, value)
                dst.fmi2SetReal(dst.component, dvr, 1, value)
        rec.fmi2GetReal(rec.component, rec_vr, 1, value)
        values.append(value[0])
    for s in slaves.values():
        s.terminate()
        s.freeInstance()
    return values


PEERS = {"libcosim": run_libcosim, "ecos": run_ecos, "fmpy": run_fmpy}
CLOCKWORK = {"clockwork": (), "clockwork-threads": ("--set", "master.threads=2"),
             "clockwork-python": ("--set", 'master.engine="python"')}


def child_command(tool: str, folder: Path, recorded: str, out: Path) -> list[str]:
    if tool in CLOCKWORK:
        # The scene file, and no plot: the peers draw none, and a run's default
        # plot (matplotlib in a process of its own) would be most of a small run's time.
        return [sys.executable, "-m", "clockwork", "run", str(folder / "scene.toml"), "--out", str(out),
                "--no-progress", "--no-plot", *CLOCKWORK[tool]]
    return [sys.executable, __file__, "--child", tool, str(folder), recorded, str(out)]


def read_values(tool: str, out: Path, recorded: str) -> list[float]:
    if tool in CLOCKWORK:
        with open(out / "timeseries.csv") as f:
            rows = list(csv.DictReader(f))
        return [float(r[recorded]) for r in rows[1:]]  # the values after each step
    return json.loads(out.read_text())


def timed(cmd: list[str]) -> tuple[float, float, int]:
    """Whole-process wall time (s), CPU time (user + system, s) and peak
    resident memory (KiB) of a child."""
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    err = p.stderr.read().decode(errors="replace")
    p.stderr.close()
    p.returncode = os.waitstatus_to_exitcode(status)
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({p.returncode}): {err.strip()[-400:]}")
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss


def agreement(values: list[float], ref: list[float]) -> tuple[float, int | None]:
    """(largest |difference| from the reference, the delay in steps at which they agree exactly, or None)."""
    diff = max((abs(a - b) for a, b in zip(values, ref)), default=math.nan)
    for lag in range(0, min(len(ref), 2000)):
        if values[lag:] == ref[:len(ref) - lag]:
            return diff, lag
    return diff, None


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--fmus", type=Path, help="folder of the Reference-FMUs' FMI 2.0 build (VanDerPol.fmu, "
                                             "Feedthrough.fmu); default: the project's stand-ins")
    p.add_argument("--sizes", type=int, nargs="+", default=[10, 100])
    p.add_argument("--systems", nargs="+", default=["chain", "wide"], choices=["chain", "wide"])
    p.add_argument("--tools", nargs="+", default=["clockwork", "clockwork-threads", "clockwork-python", "libcosim",
                                                  "ecos", "fmpy"])
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--work", type=Path, default=Path("out/bench_scale"))
    p.add_argument("--json", type=Path, help="write the measurements here too")
    p.add_argument("--load", action="store_true",
                   help="time loading instead: `clockwork validate` of the SSD and of the scene file, and "
                        "`clockwork run` to the first step, of the chain at each size")
    p.add_argument("--child", nargs=4, metavar=("TOOL", "FOLDER", "RECORDED", "OUT"), help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    if a.child:
        tool, folder, recorded, out = a.child
        Path(out).write_text(json.dumps(PEERS[tool](Path(folder), recorded)))
        return 0
    models = _models(a.fmus)
    roles = {"source"} | ({"through"} if "chain" in a.systems else set()) | ({"sink"} if "wide" in a.systems else set())
    for role in sorted(roles):
        fmu = models[role][0]
        if not fmu.is_file():
            p.error(f"{fmu} ({role}) is missing: build the project (cmake --build build) or give --fmus")
    # clockwork's bytecode up to date, as pip leaves an installed package: a
    # checkout run with PYTHONDONTWRITEBYTECODE set would compile some 45
    # modules from source in every timed process (~0.3 s each run).
    import compileall

    import clockwork

    compileall.compile_dir(Path(clockwork.__file__).parent, quiet=1)
    if a.load:
        return load_times(a.work, a.sizes, a.rounds, models)
    tools = [t for t in a.tools if t in CLOCKWORK or t == "fmpy" or _installed(t)]
    results = {}
    for kind in a.systems:
        for n in a.sizes:
            folder = a.work / f"{kind}{n}"
            recorded = write_system(folder, kind, n, models)
            runs: dict[str, list[float]] = {t: [] for t in tools}
            cpu: dict[str, list[float]] = {t: [] for t in tools}
            memory: dict[str, int] = {}
            values: dict[str, list[float]] = {}
            for r in range(a.rounds):
                for tool in tools[r % len(tools):] + tools[:r % len(tools)]:  # rotated
                    out = folder / f"out-{tool}"
                    if tool not in CLOCKWORK:
                        out = out.with_suffix(".json")
                    wall, used, rss = timed(child_command(tool, folder, recorded, out))
                    runs[tool].append(wall)
                    cpu[tool].append(used)
                    memory[tool] = max(memory.get(tool, 0), rss)
                    values[tool] = read_values(tool, out, recorded)
            ref = values.get("clockwork") or next(iter(values.values()))
            for tool in tools:
                diff, lag = agreement(values[tool], ref)
                results[(kind, n, tool)] = {"median_s": statistics.median(runs[tool]), "runs_s": runs[tool],
                                            "cpu_s": statistics.median(cpu[tool]), "cpu_runs_s": cpu[tool],
                                            "peak_kib": memory[tool], "max_diff": diff, "lag_steps": lag}
                print(f"{kind:5} N={n:5} {tool:18} {statistics.median(runs[tool]):7.3f} s  "
                      f"cpu {statistics.median(cpu[tool]):7.3f} s  "
                      f"{memory[tool] / 1024:6.1f} MiB  diff {diff:.3g}  lag {lag}", flush=True)
    for metric in ("median_s", "cpu_s"):
        _table(results, a.systems, a.sizes, tools, metric)
    _ratios(results, a.systems, a.sizes, tools)
    if a.json:
        a.json.write_text(json.dumps({"|".join(map(str, k)): v for k, v in results.items()}, indent=1))
    return 0


def load_times(work: Path, sizes: list[int], rounds: int, models: dict) -> int:
    """Loading alone: validate (SSD and scene file) and a run of one step, per chain size."""
    clockwork = [sys.executable, "-m", "clockwork"]
    kinds = {"validate SSD": lambda f: clockwork + ["validate", str(f / "SystemStructure.ssd")],
             "validate scene": lambda f: clockwork + ["validate", str(f / "scene.toml")],
             "run 1 step": lambda f: clockwork + ["run", str(f / "scene.toml"), "--out", str(f / "out-first"),
                                                  "--no-progress", "--no-plot", "--set", f"experiment.stop={STEP_S!r}"]}
    times: dict[tuple[str, int], list[tuple[float, float]]] = {}
    for n in sizes:
        folder = work / f"chain{n}"
        write_system(folder, "chain", n, models)
        for r in range(rounds):
            names = list(kinds)
            for what in names[r % len(names):] + names[:r % len(names)]:
                wall, used, _ = timed(kinds[what](folder))
                times.setdefault((what, n), []).append((wall, used))
    lo, hi = min(sizes), max(sizes)
    mid = sorted(sizes)[-2] if len(sizes) > 1 else lo
    print("| what | " + " | ".join(f"N = {n}" for n in sizes)
          + f" | exponent {lo}->{hi} | ms per component ({mid}->{hi}) |")
    print("|---|" + "---|" * len(sizes) + "---|---|")
    for what in kinds:
        for label, k in (("wall", 0), ("CPU", 1)):
            med = [statistics.median(x[k] for x in times[(what, n)]) for n in sizes]
            exp = math.log(med[-1] / med[0]) / math.log(hi / lo) if hi > lo else math.nan
            slope = (med[-1] - med[-2]) / (hi - mid) * 1e3 if hi > mid else math.nan
            print(f"| {what} ({label}) | " + " | ".join(f"{m:.3f} s" for m in med) + f" | {exp:.2f} | {slope:.3f} |")
    return 0


def _ratios(results: dict, systems, sizes, tools) -> None:
    """clockwork's time over each peer's, round by round (the two ran side by side), and their median."""
    print()
    for kind in systems:
        for n in sizes:
            for mine in [t for t in tools if t.startswith("clockwork")]:
                for peer in [t for t in tools if not t.startswith("clockwork")]:
                    for key, what in (("runs_s", "wall"), ("cpu_runs_s", "cpu")):
                        per_round = [x / y for x, y in zip(results[(kind, n, mine)][key],
                                                           results[(kind, n, peer)][key])]
                        print(f"{kind} N={n} {mine}/{peer} ({what}): median {statistics.median(per_round):.3f} "
                              f"(rounds {', '.join(f'{r:.3f}' for r in per_round)})")


def _installed(tool: str) -> bool:
    import importlib.util

    return importlib.util.find_spec({"libcosim": "libcosimpy", "ecos": "ecospy"}[tool]) is not None


def _table(results: dict, systems, sizes, tools, metric: str) -> None:
    lo, hi = min(sizes), max(sizes)
    mid = sorted(sizes)[-2] if len(sizes) > 1 else lo
    print()
    print("whole-process wall time (median)" if metric == "median_s" else "CPU time, user + system (median)")
    print("| system | tool | " + " | ".join(f"N = {n}" for n in sizes)
          + f" | exponent {lo}->{hi} | us per FMU-step | peak MiB at {hi} | result vs clockwork |")
    print("|---|---|" + "---|" * len(sizes) + "---|---|---|---|")
    for kind in systems:
        for tool in tools:
            r = [results[(kind, n, tool)] for n in sizes]
            exp = (math.log(r[-1][metric] / r[0][metric]) / math.log(hi / lo)) if hi > lo else math.nan
            marginal = ((results[(kind, hi, tool)][metric] - results[(kind, mid, tool)][metric])
                        / (hi - mid) / STEPS * 1e6) if hi > mid else math.nan
            last = r[-1]
            agree = ("the same bits" if last["max_diff"] == 0 else
                     f"max diff {last['max_diff']:.3g}" + (f", equal {last['lag_steps']} steps later"
                                                            if last["lag_steps"] else ""))
            print(f"| {kind} | {tool} | " + " | ".join(f"{x[metric]:.3f} s" for x in r)
                  + f" | {exp:.2f} | {marginal:.2f} | {last['peak_kib'] / 1024:.0f} | {agree} |")


if __name__ == "__main__":
    sys.exit(main())
