"""Ziemkiewicz Fig. 11 (App. A): the period error against the numerical step.

``step_accuracy``: the period of a free pendulum against the AGM for a
fixed internal step, for the adaptive integrator at several tolerances
against the communication step, and for the paper's explicit scheme
(App. A, Eq. A1) re-implemented here (``euler_a1_period``).
"""

from __future__ import annotations

import math

from ...errors import SimulationError
from ...physics import analytic
from ...scene.kinds import Invalid
from .. import keys
from ..context import build_system, find_component, parameters
from ..registry import register
from .clock import DAY, DEG
from .parts import Parts, check_parts, convert_keys


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
    pt = dict(point)
    pt.update(overrides)
    parts = Parts(scene, pt)
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


def _steps(cfg: dict) -> tuple[list, list, list, list]:
    """(fixed steps, rtols, communication steps, paper steps) of the study, s."""
    return (cfg.get("fixed_steps", [1e-3, 1e-2, 0.1]), cfg.get("rtols", [1e-6, 1e-9, 1e-12]),
            cfg.get("comm_steps", [1e-3, 1e-2, 0.1]), cfg.get("paper_steps", [1e-5, 1e-4]))


def _paper_columns(dt: float) -> tuple[str, str]:
    tag = f"{dt * 1e6:g}us"
    return f"paper_a1_{tag}_quantized_rel_err", f"paper_a1_{tag}_interpolated_rel_err"


def _fixed_column(h: float) -> str:
    return f"fixed_{h:g}s_rel_err"


# The result's keys for every study (the literal below), and per step.
BASE_COLUMNS = {"amplitude_deg", "periods", "paper_span_s", "E_C_agm", "default_rel_err", "default_s_per_year",
                "default_rtol", "default_master_step_s", "eq2_one_term_rel_err", "eq2_two_term_rel_err",
                "eq2_one_term_s_per_year"}


def columns(scene) -> set[str]:
    fixed, _, _, paper = _steps(scene.analysis or {})
    return BASE_COLUMNS | {c for dt in paper for c in _paper_columns(dt)} | {_fixed_column(h) for h in fixed}


def _curves(rtols: list) -> list[str]:
    """The curves, each a series column "<curve>_rel_err" against h_s."""
    return ["fixed", *(f"rtol_{r:.0e}" for r in rtols), "paper_a1_quantized", "paper_a1_interpolated"]


def series_columns(scene) -> set[str]:
    return {"h_s", *(f"{name}_rel_err" for name in _curves(_steps(scene.analysis or {})[1]))}


_check_keys = check_parts()


def _check(scene, point: dict) -> None:
    """step_accuracy's keys, and the lone free pendulum it measures."""
    _check_keys(scene, point)
    pendulum = find_component(scene, "Pendulum")
    pp = parameters(scene, point)[pendulum]
    if pp["Q"] != 0 or abs(pp.get("w_start", 0.0)) > 0 or len(scene.components) != 1:
        raise Invalid("kind", "a lone free pendulum (Q = 0) released at rest for step_accuracy")
    A = (scene.analysis or {}).get("amplitude", 5.0 * DEG)
    keys.within_fmu(scene, "amplitude", pendulum, "phi_start", (A,), "the release angle")


@register("step_accuracy", {"amplitude", "periods", "fixed_steps", "rtols", "comm_steps",
                            "paper_steps", "paper_span"}, convert_keys, columns=columns, check=_check,
          series=series_columns)
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
    parts = Parts(scene, point)
    pend, pp = parts.pendulum, parts.pp
    if pp["Q"] != 0 or abs(pp.get("w_start", 0.0)) > 0 or len(scene.components) != 1:
        raise SimulationError("step_accuracy needs a lone free pendulum (Q = 0) released at rest")
    A = cfg.get("amplitude", 5.0 * DEG)
    n = cfg.get("periods", 100)
    fixed, rtols, comm, paper = _steps(cfg)
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
    curves: dict[str, dict[float, float]] = {name: {} for name in _curves(rtols)}
    for h in fixed:
        o = {P: A, (pend, "h_max"): h, (pend, "rtol"): 0.1, (pend, "atol"): 1.0,
             ("master", "step"): max(h, base_step)}
        curves["fixed"][h] = err(_measure_period(scene, point, o, n))
        bar.update()
    for r in rtols:
        key = f"rtol_{r:.0e}"
        for c in comm:
            o = {P: A, (pend, "rtol"): r, (pend, "atol"): r * 1e-2, ("master", "step"): c}
            curves[key][c] = err(_measure_period(scene, point, o, n))
            bar.update()
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
        key = float(f"{dt:.12g}")
        quantized, interpolated = _paper_columns(dt)
        result[quantized] = curves["paper_a1_quantized"][key]
        result[interpolated] = curves["paper_a1_interpolated"][key]
    for h in fixed:
        result[_fixed_column(h)] = curves["fixed"][float(f"{h:.12g}")]
    return {"kind": "step_accuracy", "result": result, "series": series}
