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
from ctypes import c_double, c_uint

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

TOOL_MODES = {
    "clockwork": dict(time="grid", sampling="fresh", start="consistent"),
    "fmpy": dict(time="sum", sampling="held", start="zero"),
    "libcosim": dict(time="ns", sampling="held", start="consistent"),
    "ecos": dict(time="sum", sampling="held", start="consistent"),
}


class _Unit:
    """One FMU with preallocated ctypes buffers for its connected variables."""

    def __init__(self, name: str, fmu: FMU2Slave, unzip_dir: str, variables: dict):
        self.name, self.fmu, self.dir, self.vr = name, fmu, unzip_dir, variables
        self.inputs: list = []  # (input vr, source unit, source output vr)
        self.outputs: list = []  # output vrs read after a step
        self.feedthrough = False  # some connected output depends directly on an input

    def freeze(self, record_vrs: list[int]) -> None:
        self.read_vrs = self.outputs + [v for v in record_vrs if v not in self.outputs]
        self.c_read_vr = (c_uint * max(1, len(self.read_vrs)))(*self.read_vrs)
        self.c_read = (c_double * max(1, len(self.read_vrs)))()
        self.c_in_vr = (c_uint * max(1, len(self.inputs)))(*[vr for vr, _, _ in self.inputs])
        self.c_in = (c_double * max(1, len(self.inputs)))()
        self.value = {}  # output vr -> latest value


def _value_setter(fmu, var, value):
    if var.type == "Real":
        fmu.setReal([var.valueReference], [float(value)])
    elif var.type in ("Integer", "Enumeration"):
        fmu.setInteger([var.valueReference], [int(value)])
    elif var.type == "Boolean":
        fmu.setBoolean([var.valueReference], [bool(value)])
    else:
        raise ValueError(f"{var.name}: type {var.type}")


def _feedthrough_order(units: dict) -> list:
    """Units with connected feedthrough outputs, each after the feedthrough units feeding it."""
    order, state = [], {}

    def visit(u):
        if state.get(u.name) == 2:
            return
        if state.get(u.name) == 1:
            raise ValueError(f"algebraic loop through {u.name}")
        state[u.name] = 1
        for _, src, _ in u.inputs:
            if src.feedthrough:
                visit(src)
        state[u.name] = 2
        if u.feedthrough:
            order.append(u)

    for u in units.values():
        visit(u)
    return order


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
            units[name] = u = _Unit(name, fmu, d, {v.name: v for v in md.modelVariables})
            deps = {o.variable.name: o.dependencies for o in md.outputs}
            u.deps = deps
            fmu.instantiate()
            fmu.setupExperiment(startTime=t0)
            for var, value in comp.parameters.items():
                _value_setter(fmu, u.vr[var], value)
            fmu.enterInitializationMode()
        for c in scene.connections:
            src, dst = units[c.src_instance], units[c.dst_instance]
            out_vr = src.vr[c.src_var].valueReference
            if out_vr not in src.outputs:
                src.outputs.append(out_vr)
            dst.inputs.append((dst.vr[c.dst_var].valueReference, src, out_vr))
            d = src.deps.get(c.src_var)
            if d is None or len(d) > 0:  # no dependency list means "depends on every input"
                src.feedthrough = True
        rec = []
        for r in record:
            inst, var = r.split(".", 1)
            rec.append((units[inst], units[inst].vr[var].valueReference))
        for u in units.values():
            u.freeze([vr for uu, vr in rec if uu is u])
        all_units = list(units.values())
        ft_order = _feedthrough_order(units)

        def read(u: _Unit):
            u.fmu.fmi2GetReal(u.fmu.component, u.c_read_vr, len(u.read_vrs), u.c_read)
            u.value.update(zip(u.read_vrs, u.c_read))

        def transfer():  # the values waiting at each input
            for u in all_units:
                for k, (_, src, out_vr) in enumerate(u.inputs):
                    u.c_in[k] = src.value[out_vr]

        def push(u: _Unit):
            if u.inputs:
                u.fmu.fmi2SetReal(u.fmu.component, u.c_in_vr, len(u.inputs), u.c_in)

        if start == "consistent":
            # Jacobi sweeps in initialization mode; one per unit settles any
            # chain of direct feedthrough.
            for u in all_units:
                read(u)
            for _ in all_units:
                transfer()
                for u in all_units:
                    push(u)
                    read(u)
            transfer()
            for u in all_units:
                push(u)
                u.fmu.exitInitializationMode()
            for u in all_units:
                read(u)
            transfer()
            if sampling == "fresh":
                for u in ft_order:
                    push(u)
                    read(u)
                    transfer()
        elif start == "zero":
            for u in all_units:
                u.fmu.exitInitializationMode()
            for u in all_units:
                for k in range(len(u.inputs)):
                    u.c_in[k] = 0.0
        else:
            raise ValueError(start)
        if sampling not in ("fresh", "held"):
            raise ValueError(sampling)
        fresh = sampling == "fresh"

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
            for u in all_units:
                push(u)
            for u in all_units:
                u.fmu.fmi2DoStep(u.fmu.component, t, step, 0)
            for u in all_units:
                read(u)
            transfer()
            if fresh:
                # Feedthrough outputs at the new point, in dependency order.
                for u in ft_order:
                    push(u)
                    read(u)
                    transfer()
            t = t_next
            times[k] = t
            for j, (u, vr) in enumerate(rec):
                values[j, k] = u.value[vr]
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
