"""Run a kit case in clockwork's own master and write the result CSV.

The CSV is what any tool would write: a ``time`` column and one column per
signal (``<instance>.<variable>``; a single-FMU case's columns carry the
bare variable names, as a cross-check ``_out.csv``). Rows are the
master's communication points: the output grid and, with event location,
the located events in between (the tube uses the grid rows, the event
check all of them).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..engine.names import split_ref
from ..errors import SceneError, SimulationError
from .cases import Case, load_case_scene
from .csvio import write_csv


def recorded_signals(c: Case) -> list[str]:
    names = list(c.tube_signals)
    if c.switch_signal:
        names.append(c.switch_signal)
    return names


def run_clockwork(c: Case, out: str | Path, *, step: float | None = None, event_location: bool = True,
                  extra: tuple = ()) -> Path:
    """Run the case in clockwork's master (the scene's settings, or a fixed
    `step` and/or event location off) and write the CSV `out`."""
    from ..analyses.context import build_system

    overrides = list(extra)
    if step is not None:
        overrides += [f"master.step={step!r}", f"master.max_step={max(step, 0.01)!r}"]
    if not event_location:
        overrides.append("master.event_location=false")
    scene = load_case_scene(c, tuple(overrides))
    names = recorded_signals(c)
    variables = {n: {v.name for v in comp.model_description.modelVariables} for n, comp in scene.components.items()}

    def ref(signal: str) -> tuple[str, str]:
        # Instance and variable names may hold dots: the longest instance that fits.
        split = split_ref(signal, variables)
        if split is not None and split[1] in variables[split[0]]:
            return split
        if signal in variables.get("pendulum", ()):  # a single-FMU case's bare names
            return "pendulum", signal
        raise SceneError(f"{c.name}: signal {signal!r} names no variable of the case's instances "
                         f"({', '.join(variables)})")

    full = [ref(n) for n in names]
    record: dict[str, list[str]] = {}
    for inst, var in full:
        record.setdefault(inst, []).append(var)
    rows: list[list[float]] = []
    with build_system(scene, {}, record=record) as sysm:
        m = sysm.master

        def on_point(master):
            rows.append([master.t] + [sysm.output(inst, var) for inst, var in full])

        on_point(m)
        try:
            if c.jump is None:
                m.run_until(c.stop, on_point)
            else:
                t_jump, signal, _, after = c.jump
                inst, var = ref(signal)
                m.run_until(t_jump, on_point)
                sysm.instances[inst].set_values({var: after})
                m.discontinuity()
                m.run_until(c.stop, on_point)
        except SimulationError:
            raise
        except Exception as e:  # an FMU error surfaces as an exception of the engine
            raise SimulationError(f"{c.name}: {e}") from None
    data = np.array(rows)
    if not np.all(np.isfinite(data)):
        raise SimulationError(f"{c.name}: the run produced non-finite values")
    if abs(data[-1, 0] - c.stop) > 1e-9 * max(1.0, c.stop) or not math.isfinite(data[-1, 0]):
        raise SimulationError(f"{c.name}: the run ended at {data[-1, 0]!r} s instead of {c.stop!r} s")
    return write_csv(out, ["time"] + names, data)
