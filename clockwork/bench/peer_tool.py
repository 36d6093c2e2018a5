"""Run an SSP archive in one co-simulation tool; write the outputs after every step.

    python -m clockwork.bench.peer_tool TOOL X.ssp --steps N --step H --out result.npz VAR [VAR ...]

TOOL is fmpy (fmpy.ssp.simulation.simulate_ssp), libcosim (libcosimpy) or
ecos (ecospy); VAR is instance.variable (Real). The result holds `time`
(the tool's own clock after each step, s) and one array per VAR, row k
being the value after step k + 1. The tests call this in a subprocess: a
crash in a tool's native code must not take pytest down with it.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from clockwork.engine.names import split_ref


def run_fmpy(ssp: str, steps: int, h: float, names: list[str]) -> dict:
    from fmpy.ssp.simulation import simulate_ssp

    from clockwork.scene.ssp import fmpy_parameter_set

    # simulate_ssp loops `while time < stop_time`, adding h each time:
    # a stop half a step before N h gives exactly N steps.
    res = simulate_ssp(ssp, start_time=0.0, stop_time=(steps - 0.5) * h, step_size=h,
                       parameter_set=fmpy_parameter_set(ssp))
    if len(res) != steps:
        raise SystemExit(f"fmpy made {len(res)} steps instead of {steps}")
    # A row holds the time at the start of its step and the outputs after it.
    out = {"time": res["time"] + h}
    for n in names:
        out[n] = np.asarray(res[n], dtype=float)
    return out


def run_libcosim(ssp: str, steps: int, h: float, names: list[str]) -> dict:
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.WARNING)
    # The step comes from the archive's osp:FixedStepAlgorithm annotation.
    ex = CosimExecution.from_ssp_file(ssp)
    obs = CosimObserver.create_last_value()
    ex.add_observer(obs)
    refs = []
    slaves = [info.name.decode() for info in ex.slave_infos()]
    for n in names:
        # Instance and variable names may hold dots: the longest instance that fits.
        split = split_ref(n, slaves)
        if split is None:
            raise SystemExit(f"{n}: no instance of {', '.join(slaves)} is followed by a variable name")
        inst, var = split
        idx = ex.slave_index_from_instance_name(inst)
        vrs = {(v.name.decode() if isinstance(v.name, bytes) else v.name): v.reference
               for v in ex.slave_variables(idx)}
        refs.append((idx, vrs[var]))
    time = np.empty(steps)
    values = np.empty((len(names), steps))
    for k in range(steps):
        if not ex.step():
            raise SystemExit(f"libcosim: step {k + 1} failed")
        time[k] = ex.status().current_time * 1e-9
        for j, (idx, ref) in enumerate(refs):
            values[j, k] = obs.last_real_values(idx, [ref])[0]
    out = {"time": time}
    out.update({n: values[j] for j, n in enumerate(names)})
    return out


def run_ecos(ssp: str, steps: int, h: float, names: list[str]) -> dict:
    from ecospy import EcosLib, EcosSimulation

    from clockwork.scene.ssp import PARAMETER_SET

    EcosLib.set_log_level("warn")
    sim = EcosSimulation(step_size=h, ssp_path=ssp)
    # ecos applies a parameter set only when named at init.
    sim.init(parameter_set=PARAMETER_SET)
    ids = [n.replace(".", "::", 1) for n in names]
    time = np.empty(steps)
    values = np.empty((len(names), steps))
    for k in range(steps):
        time[k] = sim.step()
        for j, ident in enumerate(ids):
            values[j, k] = sim.get_real(ident)
    sim.terminate()
    out = {"time": time}
    out.update({n: values[j] for j, n in enumerate(names)})
    return out


RUNNERS = {"fmpy": run_fmpy, "libcosim": run_libcosim, "ecos": run_ecos}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("tool", choices=sorted(RUNNERS))
    p.add_argument("ssp")
    p.add_argument("--steps", type=int, required=True)
    p.add_argument("--step", type=float, required=True, help="communication step, s")
    p.add_argument("--out", required=True)
    p.add_argument("names", nargs="+", metavar="VAR")
    a = p.parse_args(argv)
    out = RUNNERS[a.tool](a.ssp, a.steps, a.step, a.names)
    np.savez(a.out, **out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
