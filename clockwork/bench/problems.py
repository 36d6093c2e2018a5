"""The benchmark's problems and their monolithic reference solutions, checked first."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..analyses.ziemkiewicz.lyapunov import running_exponent
from ..errors import SimulationError
from ..physics import analytic, reference
from .config import DAY, DEG, TWO_PI, atol


@dataclass
class SteadyPoint:
    key: str
    title: str
    params: reference.ClockParams  # the monolithic model
    ref: reference.SteadyState  # at rtol 1e-12
    target_deg: float

    @property
    def chronometer(self) -> bool:
        return self.params.escapement == "chronometer"

    @property
    def E_T(self) -> float:
        return self.ref.E_T

    @property
    def amplitude(self) -> float:
        """Mean of the two turning amplitudes, rad."""
        return 0.5 * (self.ref.amplitude + self.ref.amplitude_left)

    @property
    def guess(self) -> float:
        """Energy-balance amplitude (rad): what a user knows before solving."""
        p = self.params
        work = 4 * p.torque * p.phi_r if not self.chronometer else p.torque * (p.alpha_m2 - p.alpha_m1)
        return math.sqrt(work * p.Q / (math.pi * p.m * p.g * p.L))

    def pendulum(self, rtol: float, split: bool = False) -> dict:
        p = self.params
        return dict(L=p.L, m=p.m, g=p.g, Q=0.0 if split else p.Q, rtol=rtol, atol=atol(rtol))

    def escapement(self) -> tuple[str, dict]:
        p = self.params
        if self.chronometer:
            return "ChronometerEscapement", dict(torque=p.torque, alpha_m1=p.alpha_m1, alpha_m2=p.alpha_m2)
        return "GrasshopperEscapement", dict(torque=p.torque, phi_r=p.phi_r)

    def drag_c1(self) -> float:
        """The Pendulum's linear damping as a Drag coefficient: m L^2 omega0 / Q (N.m.s/rad)."""
        p = self.params
        return p.inertia * p.omega0 / p.Q


STEADY_POINTS = {
    "fig4a_5deg": ("Ziemkiewicz Fig. 4(a) clock at 5 deg", "grasshopper", 5.0),
    "fig4a_7deg": ("Ziemkiewicz Fig. 4(a) clock at 7 deg", "grasshopper", 7.0),
    "fig2b_chronometer": ("Ziemkiewicz Fig. 2(b) chronometer, window (-2, 0) deg, at 5 deg", "chronometer", 5.0),
}


def mean_amplitude(ss: reference.SteadyState) -> float:
    return 0.5 * (ss.amplitude + ss.amplitude_left)


def steady_point(key: str) -> SteadyPoint:
    """The operating point with its torque refined on the reference so that
    the mean turning amplitude is the target to 1e-10 (relative)."""
    title, esc, target_deg = STEADY_POINTS[key]
    A = target_deg * DEG
    base = dict(L=1.0, m=1.0, g=9.81, Q=1000.0)
    if esc == "grasshopper":
        params = reference.ClockParams(escapement="grasshopper", phi_r=2 * DEG, **base)
        M = analytic.grasshopper_torque_for_amplitude(A, params.phi_r, params.Q, params.m, params.L, params.g)
    else:
        params = reference.ClockParams(escapement="chronometer", alpha_m1=-2 * DEG, alpha_m2=0.0, **base)
        # Energy balance: M (alpha_m2 - alpha_m1) = pi m g L A^2 / Q.
        M = math.pi * params.m * params.g * params.L * A**2 / (params.Q * (params.alpha_m2 - params.alpha_m1))
    # A grows like sqrt(M): secant steps on (ln M, ln A).
    pts = []
    x = math.log(M)
    for _ in range(30):
        params = dataclasses.replace(params, torque=math.exp(x))
        ss = reference.steady_state(params)
        if ss.stalled:
            raise SimulationError(f"bench: {key}: the reference stalls at torque {math.exp(x)!r} N.m")
        y = math.log(mean_amplitude(ss) / A)
        if abs(y) < 1e-10:
            return SteadyPoint(key, title, params, ss, target_deg)
        pts.append((x, y))
        if len(pts) >= 2 and pts[-1][1] != pts[-2][1]:
            (x0, y0), (x1, y1) = pts[-2], pts[-1]
            x = x1 - y1 * (x1 - x0) / (y1 - y0)
        else:
            x -= 2.0 * y
    raise SimulationError(f"bench: {key}: no torque found for {target_deg} deg")


@dataclass(frozen=True)
class Hoyng:
    eps: float = 2.5e-4
    mu0: float = 2e-5
    mu1: float = 4e-5
    phi0: float = 0.03
    jump_periods: int = 150
    ticks: int = 1000

    @property
    def Q(self) -> float:
        return analytic.Q_from_epsilon(self.eps)

    @property
    def lam0(self) -> float:
        return analytic.hoyng_stationary_amplitude(self.mu0, self.eps, self.phi0)

    @property
    def t_jump(self) -> float:
        return self.jump_periods * TWO_PI  # omega0 = 1

    def params(self, mu: float) -> reference.ClockParams:
        return reference.ClockParams(L=1.0, g=1.0, m=1.0, Q=self.Q, escapement="grasshopper", torque=mu,
                                     phi_r=self.phi0)


def hoyng_reference(h: Hoyng, rtol: float = reference.RTOL) -> np.ndarray:
    """Tick times (s) of the monolithic solution, start on the stationary swing (phi = 0, w = lambda)."""
    a = reference.simulate(h.params(h.mu0), 0.0, h.lam0, h.t_jump, rtol=rtol, atol=atol(rtol))
    t_end = (h.ticks + 1.5) * TWO_PI
    b = reference.simulate(h.params(h.mu1), a.y[0], a.y[1], t_end, t0=h.t_jump, mode=a.mode, rtol=rtol,
                           atol=atol(rtol))
    ticks = np.concatenate([a.ticks, b.ticks])
    if len(ticks) < h.ticks:
        raise SimulationError(f"bench: the Hoyng reference has only {len(ticks)} ticks")
    return ticks


TWIN_DPHI = 1e-6 * DEG  # the twins' initial difference, rad (Z Fig. 10b)


@dataclass(frozen=True)
class Chaos:
    """Ziemkiewicz Sec. VIII: gamma1 = pi/500 (Q ~ 500), gamma2 = gamma1/100,
    omega02 = 7 omega01, kappa = 1e7, C1 = 1, C2 = 2.5; M_F = 0.5 N.cm,
    phi_r = 2 deg, start at 7 deg at rest (Fig. 10); no velocity-dependent
    friction (the reference has none)."""

    t_end: float = 400.0
    transient: float = 100.0
    sample: float = 0.05
    torque: float = 0.005
    phi_start: float = 7 * DEG

    @property
    def omega01(self) -> float:
        return math.sqrt(9.81)

    @property
    def Q(self) -> float:
        return self.omega01 / (math.pi / 500.0)

    @property
    def T0(self) -> float:
        return TWO_PI / self.omega01

    def vibration(self) -> dict:
        return dict(gamma2=math.pi / 500.0 / 100.0, omega02=7.0 * self.omega01, kappa=1e7, C1=1.0, C2=2.5)

    def params(self) -> reference.ClockParams:
        return reference.ClockParams(Q=self.Q, torque=self.torque, phi_r=2 * DEG,
                                     vibration=reference.Vibration(**self.vibration()))

    def grid(self) -> np.ndarray:
        n = int(math.floor(self.t_end / self.sample + 1e-9))
        return self.sample * np.arange(n + 1)

    def lambda2(self, t_grid, run: dict, twin: dict) -> float:
        """Ziemkiewicz's lambda2 over the whole run (1/s): the least-squares
        slope of ln d2 over [0, t_end], d2 the twins' distance in the
        mechanism's phase space (analyses/chaos.py, Fig. 10b)."""
        d2 = np.hypot(run["a2_series"] - twin["a2_series"],
                      (run["a2dot_series"] - twin["a2dot_series"]) / self.vibration()["omega02"])
        lam = running_exponent(np.asarray(t_grid), d2)
        if not np.isfinite(lam[-1]):
            raise SimulationError("bench: the twins did not part: no lambda2")
        return float(lam[-1])

    def statistics(self, ticks, t_grid, a2) -> dict:
        """Mean rate (s/day, positive: slow) from the ticks in the window, rms of a2 (rad)."""
        ticks = np.asarray(ticks)
        ticks = ticks[(ticks >= self.transient) & (ticks <= self.t_end)]
        t_grid, a2 = np.asarray(t_grid), np.asarray(a2)
        keep = t_grid >= self.transient - 1e-9
        if len(ticks) < 3 or not keep.any():
            raise SimulationError("bench: too few ticks or samples in the statistics window")
        period = (ticks[-1] - ticks[0]) / (len(ticks) - 1)
        return {"rate_s_per_day": (period / self.T0 - 1.0) * DAY, "a2_rms": float(np.sqrt(np.mean(a2[keep] ** 2))),
                "ticks": int(len(ticks))}


def chaos_reference(c: Chaos, rtol: float = reference.RTOL, dphi: float = 0.0) -> dict:
    """Statistics, and the a2, a2dot samples (``*_series``) for lambda2."""
    r = reference.simulate(c.params(), c.phi_start + dphi, 0.0, c.t_end, dense=True, rtol=rtol, atol=atol(rtol))
    t = c.grid()
    y = r.sol(t)
    stats = c.statistics(r.ticks, t, y[2])
    stats["a2_series"], stats["a2dot_series"] = y[2], y[3]
    return stats


def public_stats(stats: dict) -> dict:
    return {k: v for k, v in stats.items() if not k.endswith("_series")}
