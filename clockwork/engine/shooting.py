"""Periodic orbits by shooting: a one-period map and its fixed point.

Waiting for a transient to die out costs Q/pi periods per e-fold. Instead,
take the Poincare section at the pendulum's upward zero crossing (phi = 0,
w = W > 0), which the Pendulum FMU marks with its tick outputs: one
evaluation of the map W -> W' resets every FMU (fmi2Reset), starts the
pendulum on the section and co-simulates one full period, events located.
``shoot`` finds the fixed point W' = W by secant steps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import SimulationError
from .master import Master


@dataclass
class Orbit:
    """The best point of a shooting run."""

    W: float  # start speed on the section, rad/s
    W_end: float  # speed on the section one period later, rad/s
    period: float  # s
    amplitude_right: float  # first turning point, rad
    amplitude_left: float  # last turning point, rad
    iterations: int  # map evaluations
    rate_change: float  # last change of T / T0 between iterates (nan: no convergence test passed)


class Shooter:
    """Runs the one-period map on a Master whose pendulum is `pendulum`."""

    def __init__(self, master: Master, parameters: dict[str, dict], pendulum: str,
                 pendulum_params: dict, max_period_factor: float = 3.0):
        self.master = master
        self.parameters = parameters
        self.pendulum = pendulum
        self.L, self.g = pendulum_params["L"], pendulum_params["g"]
        self.T0 = 2 * math.pi * math.sqrt(self.L / self.g)
        self.limit = max_period_factor * self.T0
        port = master.ports[pendulum]
        need = ["tick_time", "tick_w", "amplitude"]
        self._pos = {n: port.out_names.index(n) for n in need if n in port.out_names}
        missing = [n for n in ("tick_time", "tick_w", "amplitude") if n not in self._pos]
        if missing:
            raise SimulationError(f"steady state needs {pendulum} outputs {missing} recorded")
        self.port = port
        self.evaluations = 0

    def period_map(self, W: float) -> tuple[float, float, float, float] | None:
        """(W', T, A_right, A_left) for a start on the section with speed W, or None if it stalls."""
        params = {k: dict(v) for k, v in self.parameters.items()}
        params[self.pendulum].update(phi_start=0.0, w_start=W)
        m = self.master
        m.reinitialize(params)
        self.evaluations += 1
        out = self.port.out
        i_tick, i_w, i_amp = self._pos["tick_time"], self._pos["tick_w"], self._pos["amplitude"]
        amplitudes = []
        last_amp = out[i_amp]
        t0 = m.t
        step = m.settings.step
        k = 1
        while out[i_tick] == 0.0:
            if m.t - t0 > self.limit:
                return None
            target = t0 + k * step
            if target <= m.t:
                k += 1
                continue
            m.step(target - m.t)
            if m.t >= target - 1e-12:
                k += 1
            if out[i_amp] != last_amp:
                last_amp = out[i_amp]
                amplitudes.append(last_amp)
        T = out[i_tick] - t0
        if len(amplitudes) < 2:
            return None
        return out[i_w], T, amplitudes[0], amplitudes[-1]


def shoot(shooter: Shooter, W0: float, tolerance: float, max_iterations: int = 30) -> Orbit | None:
    """Secant iteration on F(W) = W' - W from W0 until the period has
    settled to `tolerance` (relative to T0) and the secant step is tiny.
    None when the very first map evaluation finds no period."""
    T0 = shooter.T0
    r0 = shooter.period_map(W0)
    if r0 is None:
        return None
    F0 = r0[0] - W0
    W1 = r0[0] + 0.0  # a free step of the map is a good second point
    if W1 == W0:
        W1 = W0 * (1 + 1e-6)
    prev_T = r0[1]
    best = (W0, r0)
    iterations = 1
    for _ in range(max_iterations):
        r1 = shooter.period_map(W1)
        iterations += 1
        if r1 is None:
            # Stepped into the stall region: go back halfway.
            W1 = 0.5 * (W0 + W1)
            continue
        F1 = r1[0] - W1
        best = (W1, r1)
        rate_change = abs(r1[1] - prev_T) / T0
        prev_T = r1[1]
        # Converged when the period has settled and the secant step is tiny.
        # |F| alone is no test at high Q: the map is then nearly the
        # identity (|F'| ~ pi/Q), so F is small far from the fixed point.
        step_size = abs(F1 * (W1 - W0) / (F1 - F0)) if F1 != F0 else 0.0
        if F1 == 0.0 or (
            rate_change <= 0.1 * tolerance and step_size <= 1e-10 * W1
        ):
            break
        if F1 == F0:
            break
        W2 = W1 - F1 * (W1 - W0) / (F1 - F0)
        if W2 <= 0:
            W2 = 0.5 * W1
        W0, F0, W1 = W1, F1, W2
    else:
        rate_change = math.nan
    W, (W_end, T, a_right, a_left) = best
    return Orbit(W, W_end, T, a_right, a_left, iterations, rate_change)
