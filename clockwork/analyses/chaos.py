"""Analyses, plots and headlines for the chaos scenes (Ziemkiewicz Sec. VIII,
Figs. 8-10) and the step-size study of App. A (Fig. 11).

Analysis kinds (keys in docs/scenes.md style, see each converter):

- ``limit_cycle`` (Fig. 8a): the grasshopper clock from rest, its phase
  portrait spiralling onto the limit cycle; the limit-cycle amplitude from
  the last turning points and the angles where the torque switches.
- ``vibration_series`` (Figs. 8b, 9a): pendulum + escapement + the
  mechanism's vibration mode of Eq. (7); the sampled series and statistics
  of a2 after a transient: its size, its regression on a1 (the forced part
  -C2 a1 / omega02^2) and what is left (the free oscillation), how often
  sign(a2) agrees with sign(tau).
- ``poincare`` (Fig. 9b): the section at the pendulum's upward zero
  crossings: (a2, a2dot) interpolated to each tick time; statistics that
  tell a closed curve or a few points from a cloud.
- ``rate_error`` (Fig. 10a): momentary rate error per period against the
  same clock without the vibration (C1 = C2 = 0, run in lockstep), and its
  sum, the accumulated time error.
- ``lyapunov`` (Fig. 10b): twin runs started delta apart; for every t the
  least-squares exponent of the phase-space distance over [fit_start, t].
- ``step_accuracy`` (Fig. 11): the period of a free pendulum against the
  AGM for a fixed internal step, for the adaptive integrator at several
  tolerances against the communication step, and for the paper's explicit
  scheme (App. A, Eq. A1) re-implemented here.
"""

from __future__ import annotations

import math

import numpy as np

from . import register
from .basic import find_component, run_with_progress
from .. import analytic
from .. import plots as cw_plots
from ..errors import SimulationError
from ..headlines import headline
from ..scene import Invalid
from ..units import UnitError, to_radians, to_seconds

DAY = analytic.SECONDS_PER_DAY
DEG = math.pi / 180.0


# --- scene-key converters ---------------------------------------------------


def _time(key: str, v, positive: bool = True) -> float:
    try:
        t = to_seconds(v)
    except UnitError as e:
        raise Invalid(key, str(e)) from None
    if positive and not t > 0:
        raise Invalid(key, "a positive time")
    if not positive and not t >= 0:
        raise Invalid(key, "a time >= 0")
    return t


def _angle(key: str, v) -> float:
    try:
        a = to_radians(v)
    except UnitError as e:
        raise Invalid(key, str(e)) from None
    if not 0 < a <= math.pi:
        raise Invalid(key, "an angle in (0, 180] deg")
    return a


def _pos_int(key: str, v) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or v < 1:
        raise Invalid(key, "a positive integer")
    return v


def _times(key: str, v) -> list[float]:
    if not isinstance(v, list) or not v:
        raise Invalid(key, "a non-empty list of times")
    return sorted(_time(key, x) for x in v)


def _numbers(key: str, v, lo: float = 0.0, hi: float = math.inf) -> list[float]:
    if not (isinstance(v, list) and v and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                             and lo < x < hi for x in v)):
        raise Invalid(key, f"a non-empty list of numbers in ({lo:g}, {hi:g})")
    return sorted(float(x) for x in v)


_CONVERTERS = {
    "transient": lambda k, v: _time(k, v, positive=False),
    "sample_interval": _time,
    "fit_start": lambda k, v: _time(k, v, positive=False),
    "perturbation": _angle,
    "amplitude": _angle,
    "periods": _pos_int,
    "fixed_steps": _times,
    "comm_steps": _times,
    "paper_steps": _times,
    "paper_span": _time,
    "rtols": lambda k, v: _numbers(k, v, 0.0, 0.1),
}


def _convert(t: dict) -> dict:
    return {k: _CONVERTERS[k](k, v) for k, v in t.items()}


# --- shared pieces -----------------------------------------------------------


class _Parts:
    """Instance names and parameters of a chaos scene."""

    def __init__(self, scene, point: dict):
        from ..runner import parameters

        self.pendulum = find_component(scene, "Pendulum")
        self.escapement = find_component(scene, "GrasshopperEscapement")
        self.vibration = find_component(scene, "MechanismVibration")
        if self.pendulum is None:
            raise SimulationError(f"{scene.analysis['kind']}: the scene needs a Pendulum component")
        self.params = parameters(scene, point)
        self.pp = self.params[self.pendulum]
        self.esc = self.params.get(self.escapement, {})
        self.vib = self.params.get(self.vibration, {})
        for inst in (self.pendulum, self.escapement, self.vibration):
            if inst is not None:
                self._fill_defaults(scene, inst)
        self.omega0 = math.sqrt(self.pp["g"] / self.pp["L"])

    def _fill_defaults(self, scene, inst: str) -> None:
        """Parameters the scene leaves out take the FMU's start values."""
        p = self.params.setdefault(inst, {})
        for v in scene.components[inst].model_description.modelVariables:
            if v.causality == "parameter" and v.name not in p and v.type == "Real" and v.start is not None:
                p[v.name] = float(v.start)

    def need_vibration(self, kind: str) -> None:
        if self.vibration is None or self.escapement is None:
            raise SimulationError(f"{kind} needs a GrasshopperEscapement and a MechanismVibration")


def _on_grid(master, interval: float | None) -> bool:
    """True at communication points on the sample grid (events add points off it)."""
    step = master.settings.step
    k = (master.t - master.start_time) / step
    if abs(k - round(k)) > 1e-6:
        return False
    if not interval:
        return True
    j = (master.t - master.start_time) / interval
    return abs(j - round(j)) < 1e-6 * max(1.0, interval / step)


def _hermite(t: float, t0: float, t1: float, f0: float, f1: float, d0: float, d1: float) -> float:
    """Cubic Hermite interpolant of f on [t0, t1] with slopes d0, d1 at its ends."""
    h = t1 - t0
    s = (t - t0) / h
    s2, s3 = s * s, s * s * s
    return ((2 * s3 - 3 * s2 + 1) * f0 + (s3 - 2 * s2 + s) * h * d0
            + (-2 * s3 + 3 * s2) * f1 + (s3 - s2) * h * d1)


def _json_list(a) -> list:
    """JSON has no NaN: None instead."""
    return [float(v) if math.isfinite(v) else None for v in np.asarray(a, dtype=float)]


def _stats(m) -> dict:
    return vars(m.stats).copy()


# --- Fig. 8(a): the limit cycle ----------------------------------------------


@register("limit_cycle", {"sample_interval"}, _convert)
def limit_cycle(scene, point: dict, progress: bool = False) -> dict:
    from ..runner import build_system, experiment

    cfg = scene.analysis or {}
    parts = _Parts(scene, point)
    pend, esc = parts.pendulum, parts.escapement
    if esc is None:
        raise SimulationError("limit_cycle needs a GrasshopperEscapement")
    _, stop = experiment(scene, point)
    interval = cfg.get("sample_interval")
    cols = {"time": [], f"{pend}.phi": [], f"{pend}.w": [], f"{esc}.tau": []}
    turns: list[tuple[float, float]] = []
    switches: list[float] = []
    with build_system(scene, point, record={pend: ["amplitude"]}) as system:
        m = system.master
        state = {"amp": system.output(pend, "amplitude"), "tau": system.output(esc, "tau")}

        def sample(master) -> None:
            phi = system.output(pend, "phi")
            tau = system.output(esc, "tau")
            if tau * state["tau"] < 0.0:
                switches.append(phi)  # located: this point lies just past the crossing
            state["tau"] = tau
            a = system.output(pend, "amplitude")
            if a != state["amp"]:
                state["amp"] = a
                turns.append((master.t, a))
            if _on_grid(master, interval):
                cols["time"].append(master.t)
                cols[f"{pend}.phi"].append(phi)
                cols[f"{pend}.w"].append(system.output(pend, "w"))
                cols[f"{esc}.tau"].append(tau)

        sample(m)
        run_with_progress(m, stop, sample, progress, label=scene.path.stem)
        stats = _stats(m)
    if len(turns) < 6:
        raise SimulationError("limit_cycle: fewer than 6 turning points; run longer")
    amps = np.array([a for _, a in turns])
    last = amps[-4:]
    pp, e = parts.pp, parts.esc
    inertia = pp["m"] * pp["L"] ** 2
    # Eq. (B6) solved for A: the small-damping energy balance.
    a_b6 = (math.sqrt(4 * pp["Q"] * e["phi_r"] * e["torque"] / (math.pi * inertia * parts.omega0 ** 2))
            if pp["Q"] > 0 else None)
    sw = np.abs(np.asarray(switches))
    result = {
        "amplitude_start_deg": math.degrees(abs(pp["phi_start"])),
        "limit_cycle_amplitude_deg": float(np.degrees(last.mean())),
        "limit_cycle_change_deg": float(np.degrees(abs(amps[-1] - amps[-3]))),
        "amplitude_B6_deg": math.degrees(a_b6) if a_b6 else None,
        "first_turn_amplitude_deg": float(np.degrees(amps[0])),
        "turns": len(turns),
        "switches": len(switches),
        "switch_abs_phi_deg_mean": float(np.degrees(sw.mean())) if len(sw) else None,
        "switch_abs_phi_deg_max_dev": float(np.degrees(np.max(np.abs(sw - e["phi_r"])))) if len(sw) else None,
        "phi_r_deg": math.degrees(e["phi_r"]),
        "Q": pp["Q"],
        "torque_Ncm": 100.0 * e["torque"],
        # The kink in the portrait: dw/dphi = a/w jumps by 2 M/(I w) at a switch.
        "acceleration_jump_rad_per_s2": 2.0 * e["torque"] / inertia,
    }
    return {"kind": "limit_cycle", "result": result, "series": cols, "statistics": stats}


# --- Figs. 8(b), 9(a): the vibrating mechanism ------------------------------------


@register("vibration_series", {"sample_interval", "transient"}, _convert)
def vibration_series(scene, point: dict, progress: bool = False) -> dict:
    from ..runner import build_system, experiment

    cfg = scene.analysis or {}
    parts = _Parts(scene, point)
    parts.need_vibration("vibration_series")
    pend, esc, vib = parts.pendulum, parts.escapement, parts.vibration
    start, stop = experiment(scene, point)
    transient = cfg.get("transient", 0.0)
    interval = cfg.get("sample_interval")
    names = [("time", None), (f"{pend}.phi", (pend, "phi")), (f"{pend}.w", (pend, "w")),
             (f"{esc}.tau", (esc, "tau")), (f"{vib}.a2", (vib, "a2")), (f"{vib}.a2dot", (vib, "a2dot"))]
    cols: dict[str, list] = {n: [] for n, _ in names}
    ticks: list[float] = []
    record = {pend: ["tick_time", "amplitude"], vib: ["a2", "a2dot"], esc: ["tau"]}
    with build_system(scene, point, record=record) as system:
        m = system.master
        state = {"tick": system.output(pend, "tick_time"), "amp": []}

        def sample(master) -> None:
            tt = system.output(pend, "tick_time")
            if tt != state["tick"]:
                state["tick"] = tt
                ticks.append(tt)
                state["amp"].append(system.output(pend, "amplitude"))
            if _on_grid(master, interval):
                for n, src in names:
                    cols[n].append(master.t if src is None else system.output(*src))

        sample(m)
        run_with_progress(m, stop, sample, progress, label=scene.path.stem)
        stats = _stats(m)
    t = np.asarray(cols["time"])
    sel = t >= start + transient
    if sel.sum() < 10:
        raise SimulationError("vibration_series: fewer than 10 samples after the transient")
    a1 = np.asarray(cols[f"{pend}.phi"])[sel]
    a2 = np.asarray(cols[f"{vib}.a2"])[sel]
    tau = np.asarray(cols[f"{esc}.tau"])[sel]
    v = parts.vib
    w02 = v["omega02"]
    # a2 = k a1 + rest: k is the quasi-static forced response -C2/omega02^2
    # when the Duffing term is small; the rest is the free oscillation.
    k = float(np.dot(a1, a2) / np.dot(a1, a1))
    rest = a2 - k * a1
    sign_changes = int(np.count_nonzero(np.diff(np.sign(a2)) != 0))
    periods = np.diff([x for x in ticks if x >= start + transient])
    torque0 = parts.esc["torque"]
    result = {
        "transient_s": transient,
        "a2_max_abs_deg": float(np.degrees(np.max(np.abs(a2)))),
        "a2_rms_deg": float(np.degrees(np.sqrt(np.mean(a2 ** 2)))),
        "a1_max_abs_deg": float(np.degrees(np.max(np.abs(a1)))),
        "forced_gain": k,
        "forced_gain_linear": -v["C2"] / w02 ** 2,
        "free_rms_deg": float(np.degrees(np.sqrt(np.mean(rest ** 2)))),
        "duffing_over_linear": v["kappa"] * float(np.max(a2 ** 2)) / w02 ** 2,
        "sign_a2_equals_sign_tau": float(np.mean(np.sign(a2) == np.sign(tau))),
        "a2_sign_changes_per_period": (sign_changes / (len(periods)) if len(periods) else None),
        "torque_variation_percent": float(100.0 * (np.max(np.abs(tau)) / torque0 - 1.0)) if torque0 else None,
        "torque_mean_excess_percent": float(100.0 * (np.mean(np.abs(tau)) / torque0 - 1.0)) if torque0 else None,
        "amplitude_end_deg": math.degrees(state["amp"][-1]) if state["amp"] else None,
        "mean_period_s": float(periods.mean()) if len(periods) else None,
        "ticks": len(ticks),
    }
    return {"kind": "vibration_series", "result": result, "series": cols, "ticks": ticks,
            "statistics": stats}


# --- Fig. 9(b): Poincare section at a1 = 0 ------------------------------------------


def section_statistics(x: np.ndarray, y: np.ndarray, grid: int = 32) -> dict:
    """Shape statistics of section points (x, y), in any common unit.

    ring_width: IQR/median of rho = sqrt(Q(x, y)), where Q = 1 is the conic
    (ellipse) fitted by linear least squares to the points centred on their
    mean (rho = 1 on that curve; for a centred ellipse rho is the distance
    from the centre relative to the curve's). Near 0 for points on one closed, near-elliptic curve (a
    quasi-periodic orbit of a weakly nonlinear mode), of order 1 for a
    cloud. occupied_fraction: share of the cells of a grid x grid raster
    over the points' extent that hold a point, divided by the largest
    possible share min(1, n/grid^2): a few repeated points (periodic) or a
    thin curve give small values, a cloud large ones (meaningful for
    n >> grid). positive_fraction: share of points with x > 0 (both wells
    of a double well visited: ~0.5).
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    n = len(x)
    if n < 8:
        return {"n_points": n}
    scale = max(np.std(x), np.std(y)) or 1.0
    u, v = (x - x.mean()) / scale, (y - y.mean()) / scale
    M = np.column_stack([u * u, u * v, v * v, u, v])
    coef, *_ = np.linalg.lstsq(M, np.ones(n), rcond=None)
    r = np.sqrt(np.maximum(M @ coef, 0.0))
    q1, med, q3 = np.percentile(r, [25, 50, 75])
    ex, ey = np.ptp(x), np.ptp(y)
    ix = np.minimum((grid * (x - x.min()) / ex).astype(int), grid - 1) if ex > 0 else np.zeros(n, int)
    iy = np.minimum((grid * (y - y.min()) / ey).astype(int), grid - 1) if ey > 0 else np.zeros(n, int)
    cells = len(set(zip(ix.tolist(), iy.tolist())))
    return {
        "n_points": n,
        "ring_width": float((q3 - q1) / med) if med > 0 else 0.0,
        "occupied_fraction": cells / min(n, grid * grid),
        "positive_fraction": float(np.mean(x > 0)),
    }


@register("poincare", {"transient"}, _convert)
def poincare(scene, point: dict, progress: bool = False) -> dict:
    """(a2, a2dot) at each upward zero crossing of the pendulum angle.

    The Pendulum locates the crossing on its dense output (tick_time). The
    vibration state there comes from cubic Hermite interpolation over the
    communication step that holds it: a2 with slopes a2dot, a2dot with
    slopes a2ddot, all read at the step's ends. Its error is of order
    (omega h)^4/384 relative, below 1e-9 for h = 1 ms and omega ~ 22 rad/s.
    """
    from ..runner import build_system, experiment

    cfg = scene.analysis or {}
    parts = _Parts(scene, point)
    parts.need_vibration("poincare")
    pend, vib = parts.pendulum, parts.vibration
    start, stop = experiment(scene, point)
    transient = cfg.get("transient", 0.0)
    rows = {"tick_time": [], "a2": [], "a2dot": [], "tick_w": []}
    h_max = [0.0]
    record = {pend: ["tick_time", "tick_w"], vib: ["a2", "a2dot", "a2ddot"]}
    with build_system(scene, point, record=record) as system:
        m = system.master

        def state_now(master):
            return (master.t, system.output(vib, "a2"), system.output(vib, "a2dot"),
                    system.output(vib, "a2ddot"))

        prev = {"s": state_now(m), "tick": system.output(pend, "tick_time")}

        def on_point(master) -> None:
            cur = state_now(master)
            tt = system.output(pend, "tick_time")
            if tt != prev["tick"]:
                prev["tick"] = tt
                (t0, x0, v0, a0), (t1, x1, v1, a1) = prev["s"], cur
                if not t0 - 1e-12 <= tt <= t1 + 1e-12:
                    raise SimulationError(f"poincare: tick at {tt!r} s outside the step ({t0!r}, {t1!r})",
                                          time=t1)
                if tt >= start + transient:
                    rows["tick_time"].append(tt)
                    rows["a2"].append(_hermite(tt, t0, t1, x0, x1, v0, v1))
                    rows["a2dot"].append(_hermite(tt, t0, t1, v0, v1, a0, a1))
                    rows["tick_w"].append(system.output(pend, "tick_w"))
                    h_max[0] = max(h_max[0], t1 - t0)
            prev["s"] = cur

        run_with_progress(m, stop, on_point, progress, label=scene.path.stem)
        stats = _stats(m)
    w02 = parts.vib["omega02"]
    a2 = np.asarray(rows["a2"])
    v2 = np.asarray(rows["a2dot"])
    out = section_statistics(a2, v2 / w02)
    out.update({
        "C2": parts.vib["C2"],
        "transient_s": transient,
        "a2_min_deg": float(np.degrees(a2.min())) if len(a2) else None,
        "a2_max_deg": float(np.degrees(a2.max())) if len(a2) else None,
        "a2dot_min_deg_per_s": float(np.degrees(v2.min())) if len(v2) else None,
        "a2dot_max_deg_per_s": float(np.degrees(v2.max())) if len(v2) else None,
        "interpolation_step_max_s": h_max[0],
    })
    return {"kind": "poincare", "result": out, "series": rows, "statistics": stats}


# --- twins in lockstep ------------------------------------------------------------


def _lockstep(systems, stop: float, interval: float, on_sample, progress: bool, label: str) -> None:
    """Advance every system to each sample time in turn; call on_sample(t)."""
    from tqdm import tqdm

    m0 = systems[0].master
    t0 = m0.t
    n = int(math.floor((stop - t0) / interval + 1e-9))
    with tqdm(total=n, disable=not progress, delay=1.0, desc=label, unit="sample") as bar:
        for k in range(1, n + 1):
            t = min(stop, t0 + k * interval)
            for s in systems:
                s.master.run_until(t)
            on_sample(t)
            bar.update()


# --- Fig. 10(a): rate error caused by the vibration -----------------------------------


@register("rate_error", {"transient"}, _convert)
def rate_error(scene, point: dict, progress: bool = False) -> dict:
    """Periods of the clock with the vibrating mechanism against the same
    clock with C1 = C2 = 0, started alike and run in lockstep.

    Momentary error of period n: (T_n / T_ref,n - 1) in s/day (positive:
    the clock loses); accumulated error: sum of T_n - T_ref,n (s). The
    statistics skip `transient` seconds.
    """
    from ..runner import build_system, experiment

    cfg = scene.analysis or {}
    parts = _Parts(scene, point)
    parts.need_vibration("rate_error")
    pend, vib = parts.pendulum, parts.vibration
    start, stop = experiment(scene, point)
    transient = cfg.get("transient", 0.0)
    record = {pend: ["tick_time"]}
    uncoupled = dict(point)
    uncoupled[(vib, "C1")] = 0.0
    uncoupled[(vib, "C2")] = 0.0
    ticks: list[list[float]] = [[], []]
    with build_system(scene, point, record=record) as s1, build_system(scene, uncoupled, record=record) as s2:
        last = [s1.output(pend, "tick_time"), s2.output(pend, "tick_time")]

        def watch(k, s):
            def on_point(master):
                tt = s.output(pend, "tick_time")
                if tt != last[k]:
                    last[k] = tt
                    ticks[k].append(tt)
            return on_point

        s1.master.on_step = watch(0, s1)
        s2.master.on_step = watch(1, s2)
        _lockstep([s1, s2], stop, max(1.0, s1.master.settings.step), lambda t: None, progress,
                  scene.path.stem)
        stats = _stats(s1.master)
    n = min(len(ticks[0]), len(ticks[1]))
    if n < 3:
        raise SimulationError("rate_error: fewer than 3 ticks; run longer")
    t1, t2 = np.asarray(ticks[0][:n]), np.asarray(ticks[1][:n])
    T1, T2 = np.diff(t1), np.diff(t2)
    mom = (T1 / T2 - 1.0) * DAY
    acc = np.cumsum(T1 - T2)
    sel = t1[1:] >= start + transient
    m_sel = mom[sel]
    rows = {"time": list(t1[1:]), "period_s": list(T1), "reference_period_s": list(T2),
            "momentary_s_per_day": list(mom), "accumulated_s": list(acc)}
    result = {
        "transient_s": transient,
        "periods": int(n - 1),
        "momentary_mean_s_per_day": float(m_sel.mean()) if len(m_sel) else None,
        "momentary_std_s_per_day": float(m_sel.std()) if len(m_sel) else None,
        "momentary_max_abs_s_per_day": float(np.max(np.abs(m_sel))) if len(m_sel) else None,
        "momentary_p2p_s_per_day": float(np.ptp(m_sel)) if len(m_sel) else None,
        "accumulated_end_s": float(acc[-1]),
        "accumulated_max_abs_s": float(np.max(np.abs(acc))),
        "reference_period_end_s": float(T2[-1]),
    }
    return {"kind": "rate_error", "result": result, "series": rows, "statistics": stats}


# --- Fig. 10(b): Lyapunov exponents from twin runs -------------------------------------


def running_exponent(t: np.ndarray, d: np.ndarray, t_from: float = 0.0) -> np.ndarray:
    """For every t_k: least-squares slope of ln d over the samples in [t_from, t_k] (1/s).

    NaN where fewer than 3 samples or d has zeros (no difference to fit)."""
    t = np.asarray(t, dtype=float)
    d = np.asarray(d, dtype=float)
    out = np.full(len(t), np.nan)
    use = (t >= t_from) & (d > 0)
    if use.sum() < 3:
        return out
    idx = np.flatnonzero(use)
    x, y = t[idx], np.log(d[idx])
    x0 = x[0]
    x = x - x0  # conditioning
    n = np.arange(1, len(x) + 1, dtype=float)
    sx, sy = np.cumsum(x), np.cumsum(y)
    sxx, sxy = np.cumsum(x * x), np.cumsum(x * y)
    den = n * sxx - sx * sx
    with np.errstate(invalid="ignore", divide="ignore"):
        slope = (n * sxy - sx * sy) / den
    slope[:2] = np.nan
    out[idx] = slope
    return out


@register("lyapunov", {"perturbation", "sample_interval", "fit_start"}, _convert)
def lyapunov(scene, point: dict, progress: bool = False) -> dict:
    """Twin runs from phi_start and phi_start + perturbation (Ziemkiewicz Eq. 8).

    The distance of each oscillator is taken in its phase space,
    d1 = sqrt(da1^2 + (dw1/omega01)^2), d2 = sqrt(da2^2 + (da2dot/omega02)^2),
    so that it does not pass through zero twice a period as |da| does;
    lambda_i(t) is the least-squares slope of ln d_i over [fit_start, t].
    lambda_late is the slope over the second half of the run alone: an
    exponential divergence keeps it at lambda, a divergence that grows like
    a power of t makes it fall like 1/t.
    """
    from ..runner import build_system, experiment

    cfg = scene.analysis or {}
    parts = _Parts(scene, point)
    parts.need_vibration("lyapunov")
    pend, vib = parts.pendulum, parts.vibration
    start, stop = experiment(scene, point)
    delta = cfg.get("perturbation", 1e-6 * DEG)
    interval = cfg.get("sample_interval", 0.05)
    fit_start = start + cfg.get("fit_start", 0.0)
    twin = dict(point)
    twin[(pend, "phi_start")] = parts.pp["phi_start"] + delta
    record = {vib: ["a2", "a2dot"], pend: ["w"]}
    w01, w02 = parts.omega0, parts.vib["omega02"]
    rows = {"time": [], "d1": [], "d2": []}
    with build_system(scene, point, record=record) as s1, build_system(scene, twin, record=record) as s2:

        def on_sample(t):
            d1 = math.hypot(s1.output(pend, "phi") - s2.output(pend, "phi"),
                            (s1.output(pend, "w") - s2.output(pend, "w")) / w01)
            d2 = math.hypot(s1.output(vib, "a2") - s2.output(vib, "a2"),
                            (s1.output(vib, "a2dot") - s2.output(vib, "a2dot")) / w02)
            rows["time"].append(t)
            rows["d1"].append(d1)
            rows["d2"].append(d2)

        _lockstep([s1, s2], stop, interval, on_sample, progress, scene.path.stem)
        stats = _stats(s1.master)
    t = np.asarray(rows["time"])
    lam1 = running_exponent(t, rows["d1"], fit_start)
    lam2 = running_exponent(t, rows["d2"], fit_start)
    half = start + 0.5 * (stop - start)
    late1 = running_exponent(t, rows["d1"], max(half, fit_start))
    late2 = running_exponent(t, rows["d2"], max(half, fit_start))
    rows["lambda1"] = _json_list(lam1)
    rows["lambda2"] = _json_list(lam2)

    def last(x):
        x = np.asarray(x)
        return float(x[-1]) if len(x) and np.isfinite(x[-1]) else None

    def growth(d):
        d = np.asarray(d)
        sel = d[t >= fit_start]
        return float(sel[-1] / sel[0]) if len(sel) and sel[0] > 0 else None

    result = {
        "C1": parts.vib["C1"],
        "C2": parts.vib["C2"],
        "perturbation_deg": math.degrees(delta),
        "lambda1_end_per_s": last(lam1),
        "lambda2_end_per_s": last(lam2),
        "lambda1_late_per_s": last(late1),
        "lambda2_late_per_s": last(late2),
        "d1_start_rad": float(rows["d1"][0]) if rows["d1"] else None,
        "d1_end_rad": float(rows["d1"][-1]) if rows["d1"] else None,
        "d2_end_rad": float(rows["d2"][-1]) if rows["d2"] else None,
        "d1_growth": growth(rows["d1"]),
        "d2_growth": growth(rows["d2"]),
    }
    return {"kind": "lyapunov", "result": result, "series": rows, "statistics": stats}


# --- Fig. 11: period error against the numerical step -------------------------------------


def euler_a1_period(amplitude: float, dt: float, span: float, g_over_L: float = 9.81) -> tuple[float, float]:
    """Mean period of a free pendulum by Ziemkiewicz Eq. (A1), in its
    semi-implicit reading: V += a(alpha) dt, then alpha += V dt with the new
    V. (The fully explicit reading gains energy by the factor 1 + w0^2 dt^2
    per step: at 100 us the amplitude grows by 1 % per 10 periods and the
    measured period by ~5e-5 over 200 s, far from the accuracy the paper
    quotes.) Released at rest from `amplitude`; upward zero crossings over
    `span` seconds. Returns (mean period with ticks at the first step with
    alpha >= 0, mean period with ticks interpolated linearly), s.
    """
    a, v = amplitude, 0.0
    k = g_over_L * dt
    sin = math.sin
    n = int(round(span / dt))
    first_q = last_q = first_i = last_i = None
    count = 0
    prev = a
    for i in range(1, n + 1):
        v -= k * sin(a)
        a += v * dt
        if prev < 0.0 <= a:
            tq = i * dt
            ti = (i - 1) * dt + dt * (-prev) / (a - prev)
            if first_q is None:
                first_q, first_i = tq, ti
            last_q, last_i = tq, ti
            count += 1
        prev = a
    if count < 2:
        raise SimulationError(f"Eq. (A1) run of {span} s with dt = {dt} s has fewer than 2 ticks")
    return (last_q - first_q) / (count - 1), (last_i - first_i) / (count - 1)


def _measure_period(scene, point: dict, overrides: dict, n_periods: int) -> float:
    """Mean period (s) over n_periods of the scene's free pendulum."""
    from ..runner import build_system

    pt = dict(point)
    pt.update(overrides)
    parts = _Parts(scene, pt)
    pend = parts.pendulum
    T0 = analytic.small_angle_period(parts.pp["L"], parts.pp["g"])
    ticks: list[float] = []
    with build_system(scene, pt, record={pend: ["tick_time"]}) as system:
        m = system.master
        last = system.output(pend, "tick_time")
        h = m.settings.step
        while len(ticks) < n_periods + 1:
            if m.t - m.start_time > (n_periods + 2) * 2 * T0:
                raise SimulationError("step_accuracy: too few ticks (is the pendulum free and swinging?)",
                                      time=m.t)
            m.step(h)
            tt = system.output(pend, "tick_time")
            if tt != last:
                ticks.append(tt)
                last = tt
    return (ticks[-1] - ticks[0]) / n_periods


@register("step_accuracy", {"amplitude", "periods", "fixed_steps", "rtols", "comm_steps",
                            "paper_steps", "paper_span"}, _convert)
def step_accuracy(scene, point: dict, progress: bool = False) -> dict:
    """E_C(simulated) - E_C(AGM) = (T - T_AGM)/T0 of a free pendulum (Fig. 11).

    - fixed: the Pendulum's Dormand-Prince 5(4) with its step pinned to h
      (h_max = h, rtol = 0.1, atol = 1: the error control never shortens
      it); communication step max(h, master.step).
    - rtol_<x>: adaptive integration with rtol = x, atol = x/100 against
      the communication step.
    - paper_a1: Eq. (A1) (see euler_a1_period) over paper_span seconds,
      ticks at step resolution (quantized) or interpolated.
    - default: the scene's own pendulum parameters and master step.
    """
    from tqdm import tqdm

    cfg = scene.analysis or {}
    parts = _Parts(scene, point)
    pend, pp = parts.pendulum, parts.pp
    if pp["Q"] != 0 or abs(pp.get("w_start", 0.0)) > 0 or len(scene.components) != 1:
        raise SimulationError("step_accuracy needs a lone free pendulum (Q = 0) released at rest")
    A = cfg.get("amplitude", 5.0 * DEG)
    n = cfg.get("periods", 100)
    fixed = cfg.get("fixed_steps", [1e-3, 1e-2, 0.1])
    rtols = cfg.get("rtols", [1e-6, 1e-9, 1e-12])
    comm = cfg.get("comm_steps", [1e-3, 1e-2, 0.1])
    paper = cfg.get("paper_steps", [1e-5, 1e-4])
    span = cfg.get("paper_span", 2000.0)
    L, g = pp["L"], pp["g"]
    T0 = analytic.small_angle_period(L, g)
    T_agm = analytic.exact_period(A, L, g)
    base_step = scene.master.step
    P = (pend, "phi_start")
    jobs = len(fixed) + len(rtols) * len(comm) + len(paper) + 1
    bar = tqdm(total=jobs, disable=not progress, delay=1.0, desc=scene.path.stem, unit="run")

    def err(T):
        return (T - T_agm) / T0

    default = err(_measure_period(scene, point, {P: A}, n))
    bar.update()
    curves: dict[str, dict[float, float]] = {"fixed": {}}
    for h in fixed:
        o = {P: A, (pend, "h_max"): h, (pend, "rtol"): 0.1, (pend, "atol"): 1.0,
             ("master", "step"): max(h, base_step)}
        curves["fixed"][h] = err(_measure_period(scene, point, o, n))
        bar.update()
    for r in rtols:
        key = f"rtol_{r:.0e}"
        curves[key] = {}
        for c in comm:
            o = {P: A, (pend, "rtol"): r, (pend, "atol"): r * 1e-2, ("master", "step"): c}
            curves[key][c] = err(_measure_period(scene, point, o, n))
            bar.update()
    curves["paper_a1_quantized"], curves["paper_a1_interpolated"] = {}, {}
    for dt in paper:
        Tq, Ti = euler_a1_period(A, dt, span, g / L)
        curves["paper_a1_quantized"][dt] = err(Tq)
        curves["paper_a1_interpolated"][dt] = err(Ti)
        bar.update()
    bar.close()
    # One row per step; "1e-4" parsed from "100 us" and from "0.1 ms" differ in the last bit.
    curves = {name: {float(f"{h:.12g}"): v for h, v in c.items()} for name, c in curves.items()}
    hs = sorted({h for c in curves.values() for h in c})
    series = {"h_s": hs}
    for name, c in curves.items():
        series[f"{name}_rel_err"] = [c.get(h) for h in hs]
    e1 = (analytic.series_period(A, L, g, terms=1) - T_agm) / T0
    e2 = (analytic.series_period(A, L, g, terms=2) - T_agm) / T0
    result = {
        "amplitude_deg": math.degrees(A),
        "periods": n,
        "paper_span_s": span,
        "E_C_agm": analytic.circular_error(A),
        "default_rel_err": default,
        "default_s_per_year": default * DAY * 365.25,
        "default_rtol": pp["rtol"],
        "default_master_step_s": base_step,
        "eq2_one_term_rel_err": e1,
        "eq2_two_term_rel_err": e2,
        "eq2_one_term_s_per_year": e1 * DAY * 365.25,
    }
    for dt in paper:
        tag = f"{dt * 1e6:g}us"
        key = float(f"{dt:.12g}")
        result[f"paper_a1_{tag}_quantized_rel_err"] = curves["paper_a1_quantized"][key]
        result[f"paper_a1_{tag}_interpolated_rel_err"] = curves["paper_a1_interpolated"][key]
    for h in fixed:
        result[f"fixed_{h:g}s_rel_err"] = curves["fixed"][float(f"{h:.12g}")]
    return {"kind": "step_accuracy", "result": result, "series": series}


# --- plots -------------------------------------------------------------------------------------

_plt = cw_plots.plt


def _plot_keys(t: dict) -> dict:
    out = dict(t)
    for k in ("x", "y", "title"):
        if k in t and not isinstance(t[k], str):
            raise Invalid(k, "a string")
    if "file" in t:
        f = t["file"]
        if not isinstance(f, str) or not f or "/" in f or "\\" in f or f.startswith("."):
            raise Invalid("file", 'a file name without a directory, e.g. "fig.png"')
    if "window" in t:
        w = t["window"]
        if not (isinstance(w, list) and len(w) == 2):
            raise Invalid("window", "[from, to] times")
        out["window"] = [_time("window", w[0], positive=False), _time("window", w[1])]
        if out["window"][1] <= out["window"][0]:
            raise Invalid("window", "[from, to] with from < to")
    return out


def _single(results):
    if not (results and results[0] and "series" in results[0]):
        return None
    return results[0]


@cw_plots.register("phase_space", {"x", "y", "window"}, _plot_keys)
def plot_phase_space(scene, results, spec):
    """A trajectory in degrees, coloured by time; +-phi_r marked when x is the pendulum angle."""
    r = _single(results)
    if r is None:
        return None
    s = r["series"]
    t = np.asarray(s["time"])
    sel = np.ones(len(t), bool)
    if spec.get("window"):
        a, b = spec["window"]
        sel = (t >= a) & (t <= b)
    x, xl = cw_plots._display(scene, spec["x"], np.asarray(s[spec["x"]])[sel])
    y, yl = cw_plots._display(scene, spec["y"], np.asarray(s[spec["y"]])[sel])
    fig, ax = _plt.subplots(figsize=(6, 5.5))
    from matplotlib.collections import LineCollection

    pts = np.column_stack([x, y])
    lc = LineCollection(np.stack([pts[:-1], pts[1:]], axis=1), cmap="viridis", lw=0.6)
    lc.set_array(t[sel][:-1])
    ax.add_collection(lc)
    ax.autoscale()
    fig.colorbar(lc, ax=ax, label="time (s)")
    ax.plot(x[:1], y[:1], "ko", ms=4, label="start")
    esc = find_component(scene, "GrasshopperEscapement")
    pend = find_component(scene, "Pendulum")
    if esc and pend and spec["x"] == f"{pend}.phi":
        phi_r = math.degrees(scene.parameters()[esc]["phi_r"])
        for v in (phi_r, -phi_r):
            ax.axvline(v, color="0.4", ls="--", lw=0.8)
        ax.text(0.01, 0.01, "dashed: $\\pm\\alpha_r$ (torque switches: kinks)", transform=ax.transAxes,
                fontsize=7, color="0.3")
    ax.set_xlabel(xl)
    ax.set_ylabel(yl)
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(spec.get("title", scene.title), fontsize=10)
    return fig


@cw_plots.register("vibration_time", {"window"}, _plot_keys)
def plot_vibration_time(scene, results, spec):
    """a2 (deg) and the escapement torque (N.cm) against time (Fig. 9a)."""
    r = _single(results)
    if r is None:
        return None
    s = r["series"]
    vib = find_component(scene, "MechanismVibration")
    esc = find_component(scene, "GrasshopperEscapement")
    pend = find_component(scene, "Pendulum")
    t = np.asarray(s["time"])
    sel = np.ones(len(t), bool)
    if spec.get("window"):
        a, b = spec["window"]
        sel = (t >= a) & (t <= b)
    fig, ax = _plt.subplots(figsize=(9, 4))
    ax.plot(t[sel], np.degrees(np.asarray(s[f"{vib}.a2"])[sel]), color="C0", lw=0.8,
            label="$\\alpha_2$ (vibration)")
    ax.plot(t[sel], np.degrees(np.asarray(s[f"{pend}.phi"])[sel]) * r["result"]["forced_gain_linear"],
            color="C2", lw=0.8, ls="--", label="$-C_2\\alpha_1/\\omega_{02}^2$ (quasi-static)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("$\\alpha_2$ (deg)", color="C0")
    tx = ax.twinx()
    tx.plot(t[sel], 100.0 * np.asarray(s[f"{esc}.tau"])[sel], color="C1", lw=0.9, label="torque $M_F$")
    tx.set_ylabel("torque $M_F$ (N.cm)", color="C1")
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = tx.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, loc="upper right", fontsize=8)
    ax.set_title(spec.get("title", scene.title), fontsize=10)
    return fig


@cw_plots.register("poincare_map", set(), _plot_keys)
def plot_poincare(scene, results, spec):
    """One panel per sweep point: (a2, a2dot) at the upward zero crossings of a1."""
    rows = [r for r in results if r and "series" in r and r["series"].get("a2")]
    if not rows:
        return None
    fig, axes = _plt.subplots(1, len(rows), figsize=(5 * len(rows), 4.6), squeeze=False)
    for ax, r in zip(axes[0], rows):
        s, res = r["series"], r["result"]
        ax.plot(np.degrees(s["a2"]), np.degrees(s["a2dot"]), ".", ms=2.5, color="C0")
        ax.set_xlabel("$\\alpha_2$ (deg)")
        ax.set_ylabel("$\\dot\\alpha_2$ (deg/s)")
        ax.set_title(f"$C_2$ = {res['C2']:g}: {res['n_points']} points, ring width "
                     f"{res.get('ring_width', math.nan):.3g}", fontsize=9)
        ax.ticklabel_format(style="sci", scilimits=(-3, 3))
    fig.suptitle(spec.get("title", scene.title), fontsize=10)
    return fig


@cw_plots.register("rate_error", set(), _plot_keys)
def plot_rate_error(scene, results, spec):
    r = _single(results)
    if r is None:
        return None
    s = r["series"]
    t = np.asarray(s["time"])
    fig, ax = _plt.subplots(figsize=(9, 4.5))
    ax.plot(t, s["momentary_s_per_day"], color="C0", lw=0.8, label="momentary error (per period)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("momentary rate error (s/day)", color="C0")
    ax.axhline(0.0, color="0.7", lw=0.5)
    tx = ax.twinx()
    tx.plot(t, s["accumulated_s"], color="C1", lw=1.2, label="accumulated error")
    tx.set_ylabel("accumulated time error (s)", color="C1")
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = tx.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, loc="upper right", fontsize=8)
    ax.set_title(spec.get("title", scene.title), fontsize=10)
    ax.text(0.01, 0.02, "reference: the same clock with $C_1 = C_2 = 0$, run in lockstep",
            transform=ax.transAxes, fontsize=7, color="0.3")
    return fig


@cw_plots.register("lyapunov", set(), _plot_keys)
def plot_lyapunov(scene, results, spec):
    rows = [r for r in results if r and "series" in r]
    if not rows:
        return None
    fig, (ax, bx) = _plt.subplots(2, 1, figsize=(8, 7), sharex=True)
    for k, r in enumerate(rows):
        s, res = r["series"], r["result"]
        t = np.asarray(s["time"])
        lab = f"$C_1$ = {res['C1']:g}, $C_2$ = {res['C2']:g}"
        ls = "-" if res["C2"] or res["C1"] else "--"
        for name, col, sym in (("lambda1", "C0", "$\\lambda_1$ (pendulum)"),
                               ("lambda2", "C1", "$\\lambda_2$ (vibration)")):
            y = np.asarray(s[name], dtype=float)
            if np.isfinite(y).any():
                ax.plot(t, y, ls, color=col, lw=1.0, label=f"{sym}, {lab}")
        for name, col in (("d1", "C0"), ("d2", "C1")):
            d = np.asarray(s[name], dtype=float)
            if (d > 0).any():
                bx.semilogy(t, np.where(d > 0, d, np.nan), ls, color=col, lw=0.8,
                            label=f"{name}, {lab}")
    ax.axhline(0.0, color="0.6", lw=0.5)
    ax.axhline(0.05, color="C1", lw=0.5, ls=":")
    ax.axhline(0.01, color="C0", lw=0.5, ls=":")
    ax.set_ylabel("fitted exponent over [0, t] (1/s)")
    ax.set_ylim(-0.05, 0.1)
    ax.legend(loc="upper right", fontsize=7)
    ax.text(0.01, 0.02, "dotted: the paper's 0.05 ($\\lambda_2$) and 0.01 ($\\lambda_1$)",
            transform=ax.transAxes, fontsize=7, color="0.3")
    bx.set_ylabel("twin distance (rad, phase space)")
    bx.set_xlabel("time (s)")
    bx.legend(loc="lower right", fontsize=7)
    ax.set_title(spec.get("title", scene.title), fontsize=10)
    return fig


@cw_plots.register("step_accuracy", set(), _plot_keys)
def plot_step_accuracy(scene, results, spec):
    r = _single(results)
    if r is None:
        return None
    s, res = r["series"], r["result"]
    h = np.asarray(s["h_s"])
    fig, ax = _plt.subplots(figsize=(11, 5.5))
    floor = 1e-16  # exact to round-off: drawn at the floor

    def draw(col, fmt, label, **kw):
        y = np.abs(np.asarray(s[col], dtype=float))
        ok = np.isfinite(y)
        if ok.any():
            ax.loglog(h[ok], np.maximum(y[ok], floor), fmt, label=label, **kw)

    draw("fixed_rel_err", "o-", "ours: DP5(4), fixed internal step h", color="C0")
    rcols = [c for c in s if c.startswith("rtol_")]
    for k, c in enumerate(rcols):
        rt = c[len("rtol_"):-len("_rel_err")]
        draw(c, "s--", f"ours: adaptive rtol {rt}, h = communication step", color=f"C{k + 2}", ms=4)
    draw("paper_a1_quantized_rel_err", "D-", "Eq. (A1), ticks at step resolution", color="C1")
    draw("paper_a1_interpolated_rel_err", "D:", "Eq. (A1), ticks interpolated", color="C1", mfc="none")
    for key, lab, ls in (("eq2_one_term_rel_err", "Eq. (2), one term", "-."),
                         ("eq2_two_term_rel_err", "Eq. (2), two terms", ":")):
        ax.axhline(abs(res[key]), color="0.4", ls=ls, lw=0.9, label=lab)
    ax.plot([res["default_master_step_s"]], [max(abs(res["default_rel_err"]), floor)], "k*", ms=12,
            label=f"ours at default settings (rtol {res['default_rtol']:g})")
    ax.axhline(1e-7, color="r", lw=0.5, ls="--")
    ax.text(h.min(), 1.3e-7, "paper: ~1e-7 at 100 us, ~10x less at 10 us", fontsize=7, color="r")
    ax.axhline(floor, color="0.8", lw=0.5)
    ax.text(h.max(), 1.3 * floor, "values below 1e-16 drawn at 1e-16", fontsize=6, color="0.5", ha="right")
    ax.set_xlabel("numerical step h (s)")
    ax.set_ylabel("$|E_C^{sim} - E_C^{AGM}|$ (relative)")
    ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=7)
    ax.set_title(spec.get("title", scene.title), fontsize=10)
    return fig


# --- headlines -----------------------------------------------------------------------------


def _g(x) -> str:
    return "n/a" if x is None else f"{x:.3g}"


def _res(summary):
    return summary.get("result") or {}


def _points(summary):
    return [p for p in summary.get("points", []) if "error" not in p]


@headline("ziemkiewicz_fig8a")
def _h8a(scene, summary, results):
    r = _res(summary)
    return [
        {"quantity": "limit-cycle amplitude", "paper": "~7", "ours": r["limit_cycle_amplitude_deg"],
         "unit": "deg", "note": f"Q = {r['Q']:g}, torque {r['torque_Ncm']:g} N.cm, start at "
                                f"{r['amplitude_start_deg']:g} deg"},
        {"quantity": "|phi| where the torque switches (portrait kinks)", "paper": "alpha_r = 2",
         "ours": r["switch_abs_phi_deg_mean"], "unit": "deg"},
    ]


@headline("ziemkiewicz_fig8b", "ziemkiewicz_fig9a")
def _h8b(scene, summary, results):
    r = _res(summary)
    return [
        {"quantity": "max |alpha_2|", "paper": "~1 (Sec. VIII: 'for alpha_2 ~ 1 degree')",
         "ours": r["a2_max_abs_deg"], "unit": "deg",
         "note": f"quasi-static -C2 a1/omega02^2 alone: "
                 f"{abs(r['forced_gain_linear']) * r['a1_max_abs_deg']:.3g} deg"},
        {"quantity": "share of time with sign(alpha_2) = sign(M_F)",
         "paper": "square wave switching with the torque", "ours": r["sign_a2_equals_sign_tau"],
         "unit": ""},
        {"quantity": "Duffing / linear stiffness at max |alpha_2|", "paper": "Duffing dominated (chaotic)",
         "ours": r["duffing_over_linear"], "unit": ""},
    ]


@headline("ziemkiewicz_fig9b")
def _h9b(scene, summary, results):
    out = []
    for p in _points(summary):
        out.append({"quantity": f"Poincare ring width, C2 = {p['C2']:g}",
                    "paper": "regular" if p["C2"] < 2.45 else "chaotic, fractal-like",
                    "ours": p.get("ring_width"), "unit": "",
                    "note": f"{p.get('n_points')} points; occupied fraction {p.get('occupied_fraction', 0):.3g}; "
                            f"share with alpha_2 > 0: {p.get('positive_fraction', 0):.2f}"})
    return out


@headline("ziemkiewicz_fig10a")
def _h10a(scene, summary, results):
    r = _res(summary)
    return [
        {"quantity": "momentary rate error: short-term variation (peak to peak)",
         "paper": "~20, semi-random", "ours": r["momentary_p2p_s_per_day"], "unit": "s/day",
         "note": f"std {r['momentary_std_s_per_day']:.3g} s/day after {r['transient_s']:g} s"},
        {"quantity": "momentary rate error: mean against the uncoupled clock", "paper": "not given (~0 implied)",
         "ours": r["momentary_mean_s_per_day"], "unit": "s/day",
         "note": "quasi-static coupling C1 C2/(2 omega01^2 omega02^2) = 22.9 s/day"},
        {"quantity": "accumulated error at the end", "paper": "small, random-walk like",
         "ours": r["accumulated_end_s"], "unit": "s"},
    ]


@headline("ziemkiewicz_fig10b")
def _h10b(scene, summary, results):
    out = []
    for p in _points(summary):
        coupled = bool(p["C1"] or p["C2"])
        tag = f"C1 = {p['C1']:g}, C2 = {p['C2']:g}"
        out.append({"quantity": f"lambda_2 ({tag})", "paper": 0.05 if coupled else 0.0,
                    "ours": p.get("lambda2_end_per_s"), "unit": "1/s",
                    "note": f"late-half slope {_g(p.get('lambda2_late_per_s'))}; d2 grew x{_g(p.get('d2_growth'))}"})
        out.append({"quantity": f"lambda_1 ({tag})", "paper": 0.01 if coupled else 0.0,
                    "ours": p.get("lambda1_end_per_s"), "unit": "1/s",
                    "note": f"late-half slope {_g(p.get('lambda1_late_per_s'))}; d1 grew x{_g(p.get('d1_growth'))}"})
    return out


@headline("ziemkiewicz_fig11")
def _h11(scene, summary, results):
    r = _res(summary)
    out = [{"quantity": "|E_C sim - E_C AGM| at default settings", "paper": "~1e-7 (100 us), ~1e-8 (10 us)",
            "ours": abs(r["default_rel_err"]), "unit": "relative",
            "note": f"rtol {r['default_rtol']:g}, communication step {r['default_master_step_s']:g} s, "
                    f"{r['periods']} periods at {r['amplitude_deg']:g} deg"}]
    for tag, paper in (("100us", "~1e-7"), ("10us", "~1e-8")):
        k = f"paper_a1_{tag}_quantized_rel_err"
        if k in r:
            out.append({"quantity": f"Eq. (A1) at {tag.replace('us', ' us')}, {r['paper_span_s']:g} s, "
                                    "ticks at step resolution",
                        "paper": paper, "ours": abs(r[k]), "unit": "relative",
                        "note": f"ticks interpolated: {abs(r[f'paper_a1_{tag}_interpolated_rel_err']):.2g}"})
    out.append({"quantity": "Eq. (2) one term at 5 deg", "paper": "under 6 s/year (~1e-7)",
                "ours": abs(r["eq2_one_term_s_per_year"]), "unit": "s/year"})
    return out
