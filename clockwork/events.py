"""Event location: the Illinois variant of regula falsi on a step length.

The master brackets an indicator's sign change between a step length ``lo``
(no sign change) and ``hi`` (sign changed). Each trial step is a rollback
and a shorter co-simulation step; Illinois halves the weight of an end
point that is kept twice in a row, which turns regula falsi's linear
convergence superlinear without losing the bracket.
"""

from __future__ import annotations


class Illinois:
    def __init__(self, lo: float, z_lo: float, hi: float, z_hi: float):
        self.lo, self.z_lo = lo, z_lo
        self.hi, self.z_hi = hi, z_hi
        self._kept = 0  # +1: lo kept last time, -1: hi kept last time
        self.iterations = 0

    def next(self) -> float:
        """Next trial: where the secant through the bracket crosses zero."""
        dz = self.z_lo - self.z_hi
        if dz == 0.0:
            return 0.5 * (self.lo + self.hi)
        return (self.z_lo * self.hi - self.z_hi * self.lo) / dz

    def update(self, x: float, z: float, crossed: bool) -> None:
        self.iterations += 1
        if crossed:
            self.hi, self.z_hi = x, z
            if self._kept == 1:
                self.z_lo *= 0.5
            self._kept = 1
        else:
            self.lo, self.z_lo = x, z
            if self._kept == -1:
                self.z_hi *= 0.5
            self._kept = -1
