"""Ziemkiewicz Figs. 8(b), 9: the vibrating mechanism of Eq. (7).

- ``vibration_series`` (Figs. 8b, 9a): pendulum + escapement + the
  mechanism's vibration mode; the sampled series and statistics of a2 after
  a transient: its size, its regression on a1 (the forced part
  -C2 a1 / omega02^2) and what is left (the free oscillation), how often
  sign(a2) agrees with sign(tau).
- ``poincare`` (Fig. 9b): the section at the pendulum's upward zero
  crossings: (a2, a2dot) interpolated to each tick time; statistics that
  tell a closed curve or a few points from a cloud (``section_statistics``).
"""

from __future__ import annotations

import math

import numpy as np

from ...errors import SimulationError
from ..context import build_system, find_component
from ..registry import register
from ..time_series import run_with_progress
from .parts import Parts, check_parts, convert_keys, hermite, on_grid, stats_of


# The keys of the result built at the end of vibration_series.
COLUMNS = {"transient_s", "a2_max_abs_deg", "a2_rms_deg", "a1_max_abs_deg", "forced_gain", "forced_gain_linear",
           "free_rms_deg", "duffing_over_linear", "sign_a2_equals_sign_tau", "a2_sign_changes_per_period",
           "torque_variation_percent", "torque_mean_excess_percent", "amplitude_end_deg", "mean_period_s", "ticks"}


def _sampled(pend: str, esc: str, vib: str) -> list[tuple[str, tuple[str, str] | None]]:
    """The series columns and the (instance, variable) each samples (None: the time)."""
    return [("time", None), (f"{pend}.phi", (pend, "phi")), (f"{pend}.w", (pend, "w")),
            (f"{esc}.tau", (esc, "tau")), (f"{vib}.a2", (vib, "a2")), (f"{vib}.a2dot", (vib, "a2dot"))]


def series_columns(scene) -> set[str]:
    return {n for n, _ in _sampled(find_component(scene, "Pendulum"), find_component(scene, "GrasshopperEscapement"),
                                   find_component(scene, "MechanismVibration"))}


@register("vibration_series", {"sample_interval", "transient"}, convert_keys, columns=COLUMNS,
          check=check_parts(needs_vibration=True, on_grid=True, samples_after_transient=10),
          series=series_columns)
def vibration_series(scene, point: dict, progress: bool = False) -> dict:
    cfg = scene.analysis or {}
    parts = Parts(scene, point, needs_vibration=True)
    pend, esc, vib = parts.pendulum, parts.escapement, parts.vibration
    start, stop, transient = parts.start, parts.stop, parts.transient
    interval = cfg.get("sample_interval")
    names = _sampled(pend, esc, vib)
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
            if on_grid(master, interval):
                for n, src in names:
                    cols[n].append(master.t if src is None else system.output(*src))

        sample(m)
        run_with_progress(m, stop, sample, progress, label=scene.path.stem)
        stats = stats_of(m)
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


# section_statistics' keys (n_points alone under 8 points), and what poincare adds.
SECTION_COLUMNS = {"n_points", "ring_width", "occupied_fraction", "positive_fraction"}
POINCARE_COLUMNS = SECTION_COLUMNS | {"C2", "transient_s", "a2_min_deg", "a2_max_deg", "a2dot_min_deg_per_s",
                                      "a2dot_max_deg_per_s", "interpolation_step_max_s"}


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


POINCARE_SERIES = ("tick_time", "a2", "a2dot", "tick_w")


@register("poincare", {"transient"}, convert_keys, columns=POINCARE_COLUMNS, series=POINCARE_SERIES,
          check=check_parts(needs_vibration=True))
def poincare(scene, point: dict, progress: bool = False) -> dict:
    """(a2, a2dot) at each upward zero crossing of the pendulum angle.

    The Pendulum locates the crossing on its dense output (tick_time). The
    vibration state there comes from cubic Hermite interpolation over the
    communication step that holds it: a2 with slopes a2dot, a2dot with
    slopes a2ddot, all read at the step's ends. Its error is of order
    (omega h)^4/384 relative, below 1e-9 for h = 1 ms and omega ~ 22 rad/s.
    """
    parts = Parts(scene, point, needs_vibration=True)
    pend, vib = parts.pendulum, parts.vibration
    start, stop, transient = parts.start, parts.stop, parts.transient
    rows = {k: [] for k in POINCARE_SERIES}
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
                    rows["a2"].append(hermite(tt, t0, t1, x0, x1, v0, v1))
                    rows["a2dot"].append(hermite(tt, t0, t1, v0, v1, a0, a1))
                    rows["tick_w"].append(system.output(pend, "tick_w"))
                    h_max[0] = max(h_max[0], t1 - t0)
            prev["s"] = cur

        run_with_progress(m, stop, on_point, progress, label=scene.path.stem)
        stats = stats_of(m)
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
