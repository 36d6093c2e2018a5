"""Steady-state rate of a clock by shooting for its periodic orbit.

Waiting for the transient to die out costs Q/pi periods per e-fold, and a
1% amplitude error still moves the rate by about a second a day. Instead,
the Poincare section at the pendulum's upward zero crossing (phi = 0,
w = W > 0) gives a one-period map W -> W'. Each evaluation resets the FMUs
(fmi2Reset), starts the pendulum on the section and co-simulates one full
period, events located; the fixed point W' = W is found by secant steps
from the energy-balance estimate (Ziemkiewicz App. B, Hoyng Eq. 19). The
period measured on the converged orbit gives the rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from . import analytic
from .errors import SimulationError
from .master import Master


@dataclass
class SteadyState:
    stalled: bool
    amplitude: float = math.nan  # rad, mean of the two turning points
    amplitude_right: float = math.nan  # rad
    amplitude_left: float = math.nan  # rad
    period: float = math.nan  # s
    E_T: float = math.nan  # T/T0 - 1 (positive: the clock loses)
    E_C: float = math.nan  # circular error of a free pendulum of this amplitude
    E_E: float = math.nan  # E_T - E_C
    iterations: int = 0
    residual: float = math.nan  # |W' - W|, rad/s
    rate_change: float = math.nan  # last change of T/T0 between iterates
    tolerance: float = math.nan  # asked-for tolerance on E_T (dimensionless)
    reason: str = ""

    def as_dict(self) -> dict:
        d = {
            "stalled": self.stalled,
            "amplitude_deg": math.degrees(self.amplitude),
            "amplitude_right_deg": math.degrees(self.amplitude_right),
            "amplitude_left_deg": math.degrees(self.amplitude_left),
            "period_s": self.period,
            "E_T_s_per_day": self.E_T * analytic.SECONDS_PER_DAY,
            "E_C_s_per_day": self.E_C * analytic.SECONDS_PER_DAY,
            "E_E_s_per_day": self.E_E * analytic.SECONDS_PER_DAY,
            "shooting_iterations": self.iterations,
            "shooting_residual_rad_per_s": self.residual,
            "rate_tolerance_s_per_day": self.tolerance * analytic.SECONDS_PER_DAY,
            "rate_change_s_per_day": self.rate_change * analytic.SECONDS_PER_DAY,
        }
        if self.reason:
            d["reason"] = self.reason
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in d.items()}


def energy_balance_amplitude(pendulum: dict, escapement_model: str | None, escapement: dict) -> float | None:
    """Amplitude (rad) at which the escapement's work per period equals the
    damping loss 2 pi E/Q with E = m L^2 omega0^2 A^2/2, or None."""
    L, m, g, Q = pendulum["L"], pendulum["m"], pendulum["g"], pendulum["Q"]
    if Q <= 0 or escapement_model is None:
        return None
    if escapement_model == "GrasshopperEscapement":
        work = 4.0 * escapement["torque"] * escapement["phi_r"]  # App. B, Eq. (B3)
    elif escapement_model == "ChronometerEscapement":
        work = escapement["torque"] * (escapement["alpha_m2"] - escapement["alpha_m1"])
    else:
        return None
    if work <= 0:
        return 0.0
    return math.sqrt(work * Q / (math.pi * m * L * L * (g / L)))


def _velocity_at_zero(amplitude: float, L: float, g: float) -> float:
    """Speed at phi = 0 of a free pendulum of this amplitude (energy conservation)."""
    return math.sqrt(2.0 * g / L * (1.0 - math.cos(amplitude)))


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


def find_steady_state(shooter: Shooter, amplitude_guess: float, phi_r: float | None,
                      tolerance: float = 1e-3 / analytic.SECONDS_PER_DAY,
                      max_iterations: int = 30) -> SteadyState:
    """Secant iteration on F(W) = W' - W until the period has converged to `tolerance` (relative)."""
    L, g, T0 = shooter.L, shooter.g, shooter.T0
    if phi_r is not None and amplitude_guess <= phi_r:
        amplitude_guess = 1.05 * phi_r
    W0 = _velocity_at_zero(amplitude_guess, L, g)
    r0 = shooter.period_map(W0)
    if r0 is None:
        return SteadyState(stalled=True, iterations=1, tolerance=tolerance,
                           reason="no upward zero crossing within 3 nominal periods")
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
    W, (Wp, T, a_right, a_left) = best
    if not (a_right < math.pi and a_left < math.pi):
        return SteadyState(stalled=True, iterations=iterations, tolerance=tolerance,
                           reason="the torque drives the pendulum over the top: no swing")
    if phi_r is not None and min(a_right, a_left) <= phi_r:
        return SteadyState(stalled=True, iterations=iterations, tolerance=tolerance,
                           reason=f"amplitude {math.degrees(min(a_right, a_left)):.4g} deg does not exceed phi_r")
    amplitude = 0.5 * (a_right + a_left)
    if not amplitude < math.pi:
        return SteadyState(stalled=True, iterations=iterations, tolerance=tolerance,
                           reason="the torque drives the pendulum over the top: no swing")
    E_T = T / T0 - 1.0
    E_C = analytic.circular_error(amplitude)
    return SteadyState(
        stalled=False, amplitude=amplitude, amplitude_right=a_right, amplitude_left=a_left,
        period=T, E_T=E_T, E_C=E_C, E_E=E_T - E_C, iterations=iterations,
        residual=abs(Wp - W), rate_change=rate_change, tolerance=tolerance,
    )
