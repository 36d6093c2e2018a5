"""Richardson step doubling: one step of h against two of h/2.

Their difference estimates the coupling error of the step (of order
extrapolation + 1); a step whose error exceeds the tolerance is rejected
and retried shorter, and the next step's length follows the error.
"""

from __future__ import annotations


class StepDoubling:
    def __init__(self, master):
        self.master = master
        self.next_step: float | None = None  # suggested length of the next step, s

    def step(self, t: float, h: float) -> float:
        """Take an accepted step from t (a checkpoint) of at most h; returns its length, s."""
        m = self.master
        s = m.settings
        loc = m.locator
        p_order = s.extrapolation + 1
        while True:
            m.advance(t, h)
            full = m.ports.dynamic_outputs()
            m.checkpoints.rollback()
            m.advance(t, 0.5 * h)
            z_start = loc.z_start  # the indicators must span the whole step
            m.record_history()
            m.advance(t + 0.5 * h, 0.5 * h)
            loc.z_start = z_start
            half = m.ports.dynamic_outputs()
            err = max(
                (abs(a - b) / (s.richardson_tolerance * (1.0 + abs(b))) for a, b in zip(full, half)),
                default=0.0,
            ) / (2 ** p_order - 1)
            if err <= 1.0 or h <= s.min_step:
                factor = 0.9 * err ** (-1.0 / (p_order + 1)) if err > 0 else 2.0
                self.next_step = min(max(factor, 0.2), 2.0) * h
                if s.max_step:
                    self.next_step = min(self.next_step, s.max_step)
                return h
            m.stats.rejected += 1
            h = max(s.min_step, h * max(0.2, 0.9 * err ** (-1.0 / (p_order + 1))))
            m.checkpoints.rollback()
