"""The drivers of Hoyng's long run (long_run.py) on the engine's one
driver, ``Master.run_marks`` (engine/marks.py): communication points just
after each tick of the clock, and the twins' replay on a schedule of torque
changes.

*Why points after the ticks.* The escapement renews its torque noise at the
first communication point after an upward zero crossing; Hoyng renews it at
the crossing. With the master's large steps the renewal would lag by up to
a fifth of a period, and the phase at which the torque changes would then
feed a systematic phase drift of the pendulum against the averaged model
(1e-7 at a 1.26 s lag). So the next crossing is predicted from the last
tick period (torque noise moves it by ~6e-4 s) and a point is put `margin`
s after it; when the crossing comes late, short steps of `margin` follow
until it is seen. The lag is then below ~2 margin (Hoyng's grid: dt = 0.03).
"""

from __future__ import annotations

import math

from ...engine.marks import Marks

TICK_MARGIN = 2e-3  # s: a communication point this long after each expected tick


def run_tick_points(m, stop: float, watched, T0: float, on_rows, progress: bool, label: str, outputs=(),
                    before=(), margin: float = TICK_MARGIN) -> None:
    """Run `m` to `stop` with a communication point `margin` s after each
    expected tick (see the module's docstring).

    `watched`: (port, position) pairs, the first the pendulum's tick time
    (the events followed), the others what else should hand over a row
    where it changes (the escapement's torque amplitude). ``on_rows(rows)``
    gets in batches a row (t, watched values..., `outputs`..., `before`
    outputs at the point before...) at each point where a watched output
    changed. The start is a stationary one at phi = 0: the first tick comes
    near T0.
    """
    from tqdm import tqdm

    marks = Marks([m.t + T0 + margin], watched=watched, outputs=[*watched, *outputs], before=before,
                  follow=(0, T0), margin=margin)
    with tqdm(total=stop - m.t, disable=not progress, delay=1.0, desc=label, unit="s sim",
              bar_format="{l_bar}{bar}| {n:.4g}/{total:.4g} s [{elapsed}<{remaining}]") as bar:
        t_bar = [m.t]

        def on_batch(rows):
            on_rows(rows)
            bar.update(rows[-1][0] - t_bar[0])
            t_bar[0] = rows[-1][0]

        m.run_marks(stop, marks, on_batch)
        bar.update(m.t - t_bar[0])


def replay_schedule(m, times, sets, values, inputs, outputs, progress: bool, label: str,
                    chunk: int = 1 << 16) -> list[tuple]:
    """Step `m` to each of the increasing `times` (s) in turn, one step
    each (none where it stands there already); there, where sets[k], give
    values[k] to every input of `inputs` ((instance, value reference)
    pairs: a piecewise-constant drive), else read the `outputs` ((port,
    position) pairs). Returns a row (t, outputs...) per read, in chunks
    between which the progress bar moves."""
    from tqdm import tqdm

    marks = Marks(times, sets=sets, values=values, record_at_marks=True, inputs=inputs, outputs=outputs,
                  max_step=math.inf, tolerance=0.0)
    rows: list[tuple] = []
    with tqdm(total=len(times), disable=not progress, delay=1.0, desc=label, unit="event") as bar:
        for k in range(0, len(times), chunk):
            last = times[min(k + chunk, len(times)) - 1]
            m.run_marks(max(last, m.t), marks, rows.extend)
            bar.update(min(chunk, len(times) - k))
    return rows
