"""Monolithic reference solutions of the clock equations with scipy.

The pendulum (SI units, angles in rad)

    phi'' = -(g/L) sin(phi) - (omega0/Q) phi'
            + (tau_esc + tau_drag + tau_coupling) / (m L^2),   omega0 = sqrt(g/L)

(Q = 0: undamped) is driven by a grasshopper escapement (a relay with
hysteresis: Ziemkiewicz Eq. 6 with the sign of the README, Hoyng's model
escapement), a chronometer escapement or nothing; tau_drag = -(c1 w + c2 w|w|);
the optional mechanism vibration is Ziemkiewicz Eq. (7):
a2'' + gamma2 a2' + omega02^2 a2 + kappa a2^3 + C2 phi = 0, tau_coupling =
-C1 a2 m L^2.

The right-hand side is smooth between discontinuities of the escapement
(relay switch, window edges, Harrison's end of recoil) and kinks (|phi| in
the angle profiles, w|w| in the drag). Every one of them is a level crossing
of phi or w. The integration steps a DOP853 solver (the one behind
solve_ivp(method="DOP853")), locates crossings on its dense output with
brentq, and restarts the solver at each discontinuity with the new discrete
mode and the crossing component set exactly to its level. Own stepping
instead of solve_ivp's terminal events because solve_ivp re-detects an event
whose function is zero at the restart point; here a crossing needs a strict
sign on the old side, so the restart point never fires again.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import DOP853, OdeSolution
from scipy.optimize import brentq

from .analytic import circular_error, small_angle_period

RTOL = 1e-12
ATOL = 1e-14


@dataclass
class Vibration:
    """Mechanism vibration mode, Ziemkiewicz Eq. (7) (angles in rad, t in s)."""

    gamma2: float  # 1/s
    omega02: float  # rad/s
    kappa: float  # 1/(rad^2 s^2)
    C1: float  # 1/s^2, pendulum torque -C1 a2 m L^2
    C2: float  # 1/s^2
    a2_start: float = 0.0  # rad
    a2dot_start: float = 0.0  # rad/s


@dataclass
class ClockParams:
    L: float = 1.0  # m
    m: float = 1.0  # kg
    g: float = 9.81  # m/s^2
    Q: float = 1000.0  # 0 = undamped
    escapement: str = "grasshopper"  # "grasshopper" | "chronometer" | "none"
    torque: float = 0.0  # N.m (M_F)
    phi_r: float = math.radians(2.0)  # rad, grasshopper switch angle
    alpha_m1: float = math.radians(-2.0)  # rad, chronometer window
    alpha_m2: float = math.radians(2.0)  # rad
    profile: int = 0  # 0 const, 1 increasing, 2 decreasing, 3 Harrison
    profile_angle: float = math.radians(12.0)  # rad, profiles 1 and 2
    harrison_ratio: float = 2.0 / 3.0  # profile 3: recoil/drive torque
    c1: float = 0.0  # N.m.s, linear drag
    c2: float = 0.0  # N.m.s^2, quadratic drag
    vibration: Vibration | None = None

    @property
    def omega0(self) -> float:
        return math.sqrt(self.g / self.L)

    @property
    def inertia(self) -> float:
        return self.m * self.L**2

    @property
    def T0(self) -> float:
        return small_angle_period(self.L, self.g)

    @property
    def damping_rate(self) -> float:
        """omega0/Q in 1/s."""
        return self.omega0 / self.Q if self.Q > 0 else 0.0


# --- escapement modes and events ---------------------------------------------
# A mode is a tuple: grasshopper (d, recoil), chronometer (on,), none ().
# An event is (component, level, direction, action): component 0 = phi,
# 1 = w; direction +1 up, -1 down, 0 both; action(mode, y) -> new mode, or
# None for a kink (restart, same mode).


def initial_mode(p: ClockParams, phi: float, w: float, d: int | None = None) -> tuple:
    """Escapement mode at a state; the grasshopper rule is the FMU's
    (w >= 0: +1 if phi < phi_r else -1; w < 0: -1 if phi > -phi_r else +1)."""
    if p.escapement == "grasshopper":
        if d is None:
            if w >= 0.0:
                d = 1 if phi < p.phi_r else -1
            else:
                d = -1 if phi > -p.phi_r else 1
        return (d, d * w < 0.0)
    if p.escapement == "chronometer":
        return (p.alpha_m1 <= phi < p.alpha_m2 and w > 0.0,)
    if p.escapement == "none":
        return ()
    raise ValueError(f"unknown escapement {p.escapement!r}")


def _profile_factor(p: ClockParams, phi: float, recoil: bool) -> float:
    if p.profile == 0:
        return 1.0
    if p.profile == 1:
        return 0.5 + abs(phi) / p.profile_angle
    if p.profile == 2:
        return max(0.0, 1.5 - abs(phi) / p.profile_angle)
    if p.profile == 3:
        return p.harrison_ratio if recoil else 1.0
    raise ValueError(f"unknown profile {p.profile}")


def escapement_torque(p: ClockParams, mode: tuple, phi: float) -> float:
    """tau_esc in N.m for a given mode."""
    if p.escapement == "grasshopper":
        d, recoil = mode
        return d * p.torque * _profile_factor(p, phi, recoil)
    if p.escapement == "chronometer":
        return p.torque if mode[0] else 0.0
    return 0.0


def _escapement_events(p: ClockParams, mode: tuple) -> list:
    ev = []
    if p.escapement == "grasshopper":
        d, recoil = mode
        # Relay: +1 until phi rises past +phi_r, -1 until it falls past -phi_r.
        ev.append((0, d * p.phi_r, d, lambda m, y: (-m[0], True)))
        if p.profile == 3 and recoil:
            # Recoil ends at the turning point.
            ev.append((1, 0.0, d, lambda m, y: (m[0], False)))
        if p.profile in (1, 2):
            ev.append((0, 0.0, 0, None))
        if p.profile == 2:
            ev.append((0, 1.5 * p.profile_angle, 0, None))
            ev.append((0, -1.5 * p.profile_angle, 0, None))
    elif p.escapement == "chronometer":
        m1, m2 = p.alpha_m1, p.alpha_m2
        if mode[0]:
            ev.append((0, m2, 1, lambda m, y: (False,)))
            ev.append((1, 0.0, -1, lambda m, y: (False,)))  # turns inside the window
        else:
            ev.append((0, m1, 1, lambda m, y: (True,)))
            ev.append((1, 0.0, 1, lambda m, y: (m1 <= y[0] < m2,)))
    if p.c2 != 0.0:
        ev.append((1, 0.0, 0, None))
    return ev


def _make_rhs(p: ClockParams, mode: tuple):
    k = p.g / p.L
    gamma = p.damping_rate
    inv_i = 1.0 / p.inertia
    c1, c2 = p.c1, p.c2
    vib = p.vibration

    def rhs(t, y):
        phi, w = y[0], y[1]
        tau = escapement_torque(p, mode, phi) - (c1 * w + c2 * w * abs(w))
        if vib is None:
            return np.array([w, -k * math.sin(phi) - gamma * w + tau * inv_i])
        a2, v2 = y[2], y[3]
        acc = -k * math.sin(phi) - gamma * w + tau * inv_i - vib.C1 * a2
        acc2 = -vib.gamma2 * v2 - vib.omega02**2 * a2 - vib.kappa * a2**3 - vib.C2 * phi
        return np.array([w, acc, v2, acc2])

    return rhs


# --- integration core -----------------------------------------------------------


def _crossing(g_old: float, g_new: float, direction: int) -> bool:
    up = g_old < 0.0 <= g_new
    down = g_old > 0.0 >= g_new
    return (up and direction >= 0) or (down and direction <= 0)


def _root(sol, comp: int, level: float, a: float, b: float) -> float:
    fa = sol(a)[comp] - level
    fb = sol(b)[comp] - level
    if fb == 0.0:
        return b
    if fa * fb > 0.0:  # rounding at an endpoint
        return a if abs(fa) < abs(fb) else b
    return brentq(lambda s: sol(s)[comp] - level, a, b, xtol=1e-300, rtol=4 * np.finfo(float).eps, maxiter=200)


@dataclass
class SimResult:
    t: float  # s, final time
    y: np.ndarray  # final state [phi, w(, a2, a2dot)]
    mode: tuple  # final escapement mode
    ticks: np.ndarray  # s, upward zero crossings of phi
    turn_times: np.ndarray  # s, turning points (w = 0)
    turn_phi: np.ndarray  # rad, phi at the turning points
    switch_times: np.ndarray  # s, escapement mode changes
    sol: OdeSolution | None = None  # dense trajectory if requested
    steps: int = 0

    @property
    def periods(self) -> np.ndarray:
        return np.diff(self.ticks)


def _run(p, t0, y0, mode, t_end, *, stop_right_turns=None, dense=False, rtol=RTOL, atol=ATOL):
    """Integrate from t0 to t_end (or to the n-th right turning point)."""
    y = np.array(y0, dtype=float)
    t = float(t0)
    ticks, turn_t, turn_phi, switches = [], [], [], []
    ts, interps = [t], []
    right_turns, steps = 0, 0
    h = None
    while t < t_end:
        events = _escapement_events(p, mode)
        solver = DOP853(_make_rhs(p, mode), t, y, t_end, rtol=rtol, atol=atol,
                        first_step=None if h is None else min(h, t_end - t))
        restarted = False
        while solver.status == "running" and not restarted:
            t_old, y_old = solver.t, solver.y.copy()
            solver.step()
            steps += 1
            if solver.status == "failed":
                raise RuntimeError(f"DOP853 failed at t = {t_old!r} s")
            t_new, y_new = solver.t, solver.y
            h = t_new - t_old
            sol = None
            roots = {}

            def root(comp, level):
                nonlocal sol
                if (comp, level) not in roots:
                    if sol is None:
                        sol = solver.dense_output()
                    roots[comp, level] = _root(sol, comp, level, t_old, t_new)
                return roots[comp, level]

            # Earliest mode change or kink in this step.
            t_hit, hit = math.inf, None
            for comp, level, direction, action in events:
                if _crossing(y_old[comp] - level, y_new[comp] - level, direction):
                    tr = root(comp, level)
                    if tr < t_hit:
                        y_r = sol(tr)
                        new_mode = mode if action is None else action(mode, y_r)
                        if action is None or new_mode != mode:
                            t_hit, hit = tr, (comp, level, new_mode)
            t_stop = math.inf
            # Records (ticks, turning points) up to the earliest hit.
            if _crossing(y_old[0], y_new[0], 1):
                tr = root(0, 0.0)
                if tr <= t_hit:
                    ticks.append(tr)
            if _crossing(y_old[1], y_new[1], 0):
                tr = root(1, 0.0)
                if tr <= t_hit:
                    turn_t.append(tr)
                    turn_phi.append(sol(tr)[0])
                    if y_old[1] > 0.0 and stop_right_turns is not None:
                        right_turns += 1
                        if right_turns >= stop_right_turns:
                            t_stop = tr
            t_cut = min(t_hit, t_stop)
            if t_cut < math.inf:
                y = sol(t_cut)
                if t_stop <= t_hit:
                    y[1] = 0.0
                if t_hit <= t_stop:
                    comp, level, new_mode = hit
                    y[comp] = level
                    if new_mode != mode:
                        switches.append(t_hit)
                    mode = new_mode
                t = t_cut
                if dense and t_cut > t_old:
                    ts.append(t_cut)
                    interps.append(sol)
                restarted = True
                if t_stop <= t_hit:
                    t_end = t  # done
            else:
                t, y = t_new, y_new.copy()
                if dense:
                    ts.append(t_new)
                    interps.append(solver.dense_output())
    return SimResult(
        t=t, y=y, mode=mode,
        ticks=np.array(ticks), turn_times=np.array(turn_t), turn_phi=np.array(turn_phi),
        switch_times=np.array(switches),
        sol=OdeSolution(ts, interps) if dense and interps else None,
        steps=steps,
    )


def simulate(params: ClockParams, phi0: float, w0: float, t_end: float, *, t0: float = 0.0,
             mode: int | tuple | None = None, vib0: tuple[float, float] | None = None,
             dense: bool = False, rtol: float = RTOL, atol: float = ATOL) -> SimResult:
    """Integrate the clock from (phi0 rad, w0 rad/s) at t0 to t_end (s).

    mode: grasshopper relay mode d (+1/-1) or a full mode tuple from a
    previous SimResult; None derives it from the state (see initial_mode).
    vib0: (a2, a2dot) of the vibration mode, default from params.vibration.
    """
    if isinstance(mode, tuple):
        m0 = mode
    else:
        m0 = initial_mode(params, phi0, w0, mode)
    y0 = [phi0, w0]
    if params.vibration is not None:
        v = params.vibration
        y0 += list(vib0) if vib0 is not None else [v.a2_start, v.a2dot_start]
    return _run(params, t0, y0, m0, t_end, dense=dense, rtol=rtol, atol=atol)


# --- periodic orbit by shooting --------------------------------------------------


@dataclass
class SteadyState:
    amplitude: float  # rad, turning point phi = A > 0
    period: float  # s, T'
    E_T: float  # T'/T0 - 1
    E_C: float  # circular error at A
    E_E: float  # E_T - E_C, positive = slower clock
    amplitude_left: float = math.nan  # rad, |phi| at the left turning point
    stalled: bool = False
    residual: float = 0.0  # rad, A' - A at the returned orbit
    map_evaluations: int = 0
    notes: list = field(default_factory=list)


def _one_period(params: ClockParams, A: float, rtol: float, atol: float) -> SimResult:
    res = _run(params, 0.0, [A, 0.0], initial_mode(params, A, 0.0), 50.0 * params.T0,
               stop_right_turns=1, rtol=rtol, atol=atol)
    if res.y[1] != 0.0:
        raise RuntimeError(f"no return to a right turning point from A = {A!r} rad")
    return res


def return_map(params: ClockParams, A: float, rtol: float = RTOL, atol: float = ATOL):
    """One period from the turning point (phi = A, w = 0) to the next right
    turning point: returns (A' rad, T s)."""
    res = _one_period(params, A, rtol, atol)
    return res.y[0], res.t


def _work_per_period(p: ClockParams) -> float:
    """Escapement work per period (J) for the initial guess (Z Eq. B3 / Eq. 4)."""
    if p.escapement == "grasshopper":
        return 4.0 * p.torque * p.phi_r
    if p.escapement == "chronometer":
        return p.torque * (p.alpha_m2 - p.alpha_m1)
    return 0.0


def _amplitude_guess(p: ClockParams) -> float:
    """Energy balance W = 2 pi E / Q_eff + (8/3) c2 omega0^2 A^3, E = m g L A^2/2."""
    W = _work_per_period(p)
    lin = (p.damping_rate + p.c1 / p.inertia) * p.inertia * p.omega0 * math.pi  # J/rad^2
    cub = 8.0 / 3.0 * p.c2 * p.omega0**2
    if W <= 0.0:
        return math.nan
    if lin == 0.0 and cub == 0.0:
        raise ValueError("no damping: the escapement's work is never balanced")
    return brentq(lambda A: lin * A**2 + cub * A**3 - W, 0.0, 1e3)


def steady_state(params: ClockParams, amplitude_guess: float | None = None, rtol: float = 1e-12,
                 a_max: float = 3.0) -> SteadyState:
    """Periodic orbit by shooting on the Poincare section (phi = A > 0, w = 0).

    Solves A'(A) = A with brentq after bracketing around the energy-balance
    guess. stalled=True when no orbit with A above the smallest amplitude
    that can take energy (phi_r for the grasshopper, alpha_m1 for a
    chronometer whose window starts at phi > 0) exists. A chronometer whose
    window contains phi = 0 always has an orbit; for a small torque it turns
    inside the window (A < alpha_m2) and is pushed over its whole rising swing.

    E_C is taken at the right turning point A, the largest amplitude of the
    swing; the amplitude decays by about pi/(2Q) over a free half swing
    (amplitude_left), which shifts E_E by up to E_C(A) - E_C(amplitude_left).
    """
    p = params
    if p.vibration is not None:
        raise ValueError("the vibrating mechanism has no 1-D return map; use simulate()")
    if p.escapement == "none":
        raise ValueError("no escapement: no self-sustained orbit")
    a_min = p.phi_r if p.escapement == "grasshopper" else max(p.alpha_m1, 0.0)
    T0 = p.T0
    count = 0

    def stalled(note):
        return SteadyState(math.nan, math.nan, math.nan, math.nan, math.nan, stalled=True,
                           residual=math.nan, map_evaluations=count, notes=[note])

    if p.torque <= 0.0:
        return stalled("no driving torque")
    A = amplitude_guess if amplitude_guess is not None else _amplitude_guess(p)
    A = min(max(A, a_min + 1e-3 * max(a_min, 1e-2)), a_max)
    cache = {}

    def f(a):
        nonlocal count
        if a not in cache:
            count += 1
            cache[a] = _one_period(p, a, rtol, ATOL)
        return cache[a].y[0] - a

    fa = f(A)
    if fa > 0.0:
        lo, hi = A, A
        while f(hi) > 0.0:
            lo = hi
            hi = a_min + 1.5 * (hi - a_min)
            if hi > a_max:
                raise ValueError(f"the amplitude grows beyond {a_max} rad: no orbit")
    else:
        lo, hi = A, A
        while f(lo) <= 0.0:
            hi = lo
            lo = a_min + 0.5 * (lo - a_min)
            if lo - a_min < 1e-9 * max(a_min, 1e-3):
                return stalled(f"A' < A for all A down to {lo!r} rad")
    a_star = brentq(f, lo, hi, xtol=1e-300, rtol=4 * np.finfo(float).eps, maxiter=200)
    f(a_star)
    orbit = cache[a_star]
    E_T = orbit.t / T0 - 1.0
    E_C = circular_error(a_star)
    left = orbit.turn_phi[orbit.turn_phi < 0.0]
    return SteadyState(amplitude=a_star, period=orbit.t, E_T=E_T, E_C=E_C, E_E=E_T - E_C,
                       amplitude_left=-left[0] if left.size else math.nan,
                       residual=orbit.y[0] - a_star, map_evaluations=count)
