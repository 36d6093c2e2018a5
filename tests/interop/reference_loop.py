"""A fixed-step Jacobi co-simulation loop on raw fmpy FMU2Slave calls.

It reproduces, call for call, what a fixed-step zero-order-hold Jacobi
master does, with the three places where the tools differ by design as
switches:

time      "grid": t_k = t0 + k h, step t_{k+1} - t_k (clockwork's master)
          "sum":  t_{k+1} = t_k + h, step h (fmpy's simulate_ssp, ecos)
          "ns":   integer nanoseconds, t_k = k h_ns / 1e9, step t_{k+1} - t_k (libcosim)
sampling  "fresh": after every step the inputs are set at the new
          communication point and the outputs read again, so a
          direct-feedthrough output (escapement torque, drag torque) passed
          on is the value at that point (clockwork)
          "held": an output is read once, right after the FMU's doStep,
          i.e. computed from the inputs of the step's start, and that value
          is what the connected input gets for the next step (fmpy, libcosim,
          ecos): a feedthrough output reaches its destination one step late
start     "consistent": in initialization mode the inputs are iterated to
          the outputs (clockwork, libcosim, ecos)
          "zero": the FMUs initialize with their own input start values, and
          every connected input is 0 during the first step (fmpy's
          connectors all start at 0)

The tests use it twice: with clockwork's switches it must agree with
clockwork's master, with a tool's switches with the tool.
"""

from __future__ import annotations

import shutil
import tempfile
from dataclasses import dataclass

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

TOOL_MODES = {
    "clockwork": dict(time="grid", sampling="fresh", start="consistent"),
    "fmpy": dict(time="sum", sampling="held", start="zero"),
    "libcosim": dict(time="ns", sampling="held", start="consistent"),
    "ecos": dict(time="sum", sampling="held", start="consistent"),
}


@dataclass
class _Unit:
    name: str
    fmu: FMU2Slave
    dir: str
    vr: dict
    inputs: list  # (input vr, source unit name, source output vr)
    outputs: list  # output vrs to read


def _value_setter(fmu, var, value):
    if var.type == "Real":
        fmu.setReal([var.valueReference], [float(value)])
    elif var.type in ("Integer", "Enumeration"):
        fmu.setInteger([var.valueReference], [int(value)])
    elif var.type == "Boolean":
        fmu.setBoolean([var.valueReference], [bool(value)])
    else:
        raise ValueError(f"{var.name}: type {var.type}")


def run(scene, steps: int, record: list[str], time: str = "grid", sampling: str = "fresh",
        start: str = "consistent") -> dict[str, np.ndarray]:
    """Run `steps` steps of scene.master.step; returns {"time", VAR: values after each step}."""
    h = scene.master.step
    t0 = scene.experiment.start
    units: dict[str, _Unit] = {}
    try:
        for name, comp in scene.components.items():
            md = read_model_description(str(comp.fmu_path), validate=False)
            d = extract(str(comp.fmu_path))
            fmu = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier,
                            instanceName=name)
            variables = {v.name: v for v in md.modelVariables}
            units[name] = _Unit(name, fmu, d, variables, [], [])
            fmu.instantiate()
            fmu.setupExperiment(startTime=t0)
            for var, value in comp.parameters.items():
                _value_setter(fmu, variables[var], value)
            fmu.enterInitializationMode()
        for c in scene.connections:
            src, dst = units[c.src_instance], units[c.dst_instance]
            out_vr = src.vr[c.src_var].valueReference
            if out_vr not in src.outputs:
                src.outputs.append(out_vr)
            dst.inputs.append((dst.vr[c.dst_var].valueReference, c.src_instance, out_vr))
        rec = []
        for r in record:
            inst, var = r.split(".", 1)
            rec.append((inst, units[inst].vr[var].valueReference))

        out_values = {n: {} for n in units}  # latest output values {vr: value}
        held = {n: {} for n in units}  # values waiting at each input {vr: value}

        def read(u: _Unit):
            vrs = u.outputs + [vr for inst, vr in rec if inst == u.name]
            vals = u.fmu.getReal(vrs)
            out_values[u.name].update(zip(vrs, vals))

        def transfer():
            for u in units.values():
                for in_vr, src, out_vr in u.inputs:
                    held[u.name][in_vr] = out_values[src][out_vr]

        def push(u: _Unit):
            if u.inputs:
                vrs = [vr for vr, _, _ in u.inputs]
                u.fmu.setReal(vrs, [held[u.name][vr] for vr in vrs])

        n_units = len(units)
        if start == "consistent":
            # Jacobi sweeps in initialization mode; one per unit settles any
            # chain of direct feedthrough.
            for u in units.values():
                read(u)
            for _ in range(n_units):
                transfer()
                for u in units.values():
                    push(u)
                    read(u)
            transfer()
            for u in units.values():
                push(u)
                u.fmu.exitInitializationMode()
            for u in units.values():
                read(u)
            transfer()
            if sampling == "fresh":
                for u in units.values():
                    push(u)
                    read(u)
                transfer()
        elif start == "zero":
            for u in units.values():
                u.fmu.exitInitializationMode()
            for u in units.values():
                for in_vr, _, _ in u.inputs:
                    held[u.name][in_vr] = 0.0
        else:
            raise ValueError(start)

        h_ns = round(h * 1e9)
        t = t0
        times = np.empty(steps)
        values = np.empty((len(record), steps))
        for k in range(steps):
            if time == "grid":
                t_next = t0 + (k + 1) * h
            elif time == "sum":
                t_next = t + h
            elif time == "ns":
                t_next = (round(t0 * 1e9) + (k + 1) * h_ns) / 1e9
            else:
                raise ValueError(time)
            step = h if time == "sum" else t_next - t
            for u in units.values():
                push(u)
            for u in units.values():
                u.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=step)
            for u in units.values():
                read(u)
            transfer()
            if sampling == "fresh":
                # Feedthrough outputs at the new point: sweeps as in the
                # initialization (one per unit).
                for _ in range(n_units):
                    for u in units.values():
                        push(u)
                        read(u)
                    transfer()
            elif sampling != "held":
                raise ValueError(sampling)
            t = t_next
            times[k] = t
            for j, (inst, vr) in enumerate(rec):
                values[j, k] = out_values[inst][vr]
        result = {"time": times}
        result.update({r: values[j] for j, r in enumerate(record)})
        return result
    finally:
        for u in units.values():
            try:
                u.fmu.terminate()
                u.fmu.freeInstance()
            except Exception:
                pass
            shutil.rmtree(u.dir, ignore_errors=True)


def run_as(tool: str, scene, steps: int, record: list[str]) -> dict[str, np.ndarray]:
    return run(scene, steps, record, **TOOL_MODES[tool])
