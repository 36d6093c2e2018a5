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

from ..errors import SimulationError
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
    full = [n if "." in n else f"pendulum.{n}" for n in names]
    record: dict[str, list[str]] = {}
    for n in full:
        inst, var = n.split(".", 1)
        record.setdefault(inst, []).append(var)
    rows: list[list[float]] = []
    with build_system(scene, {}, record=record) as sysm:
        m = sysm.master

        def on_point(master):
            rows.append([master.t] + [sysm.output(*n.split(".", 1)) for n in full])

        on_point(m)
        try:
            if c.jump is None:
                m.run_until(c.stop, on_point)
            else:
                t_jump, signal, _, after = c.jump
                inst, var = signal.split(".", 1)
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
