"""Rows of clockwork's own master (and of scipy) on the benchmark's problems."""

from __future__ import annotations

import dataclasses

import numpy as np

from ..analyses.steady_state import find_steady_state
from ..engine.recording import Recorder
from ..engine.settings import MasterSettings
from ..engine.shooting import Shooter
from ..engine.system import System
from ..errors import SimulationError
from ..physics import reference
from .config import BenchConfig, DAY, DEG, DRAG_LINKS, Family, GRASSHOPPER_LINKS, Row, TWO_PI, VIBRATION_LINKS, atol, master_settings, timed
from .problems import Chaos, Hoyng, SteadyPoint


def _system(components, links, settings, record):
    return System(components, links, settings, record=record)


def steady_components(pt: SteadyPoint, fam: Family, rtol: float, start: dict | None = None):
    pend = pt.pendulum(rtol, fam.split)
    if start:
        pend.update(start)
    esc_model, esc = pt.escapement()
    comps = {"pendulum": ("Pendulum", pend), "escapement": (esc_model, esc)}
    links = list(GRASSHOPPER_LINKS)
    if fam.split:
        comps["drag"] = ("Drag", {"c1": pt.drag_c1()})
        links += DRAG_LINKS
    return comps, links


def build_time(pt: SteadyPoint, cfg: BenchConfig) -> float:
    """Median wall time (s) of building and freeing the two-FMU system alone."""
    comps, links = steady_components(pt, Family("build"), 1e-12)

    def build():
        with _system(comps, links, MasterSettings(step=0.5), {"pendulum": ["tick_time", "tick_w", "amplitude"]}):
            pass

    build()  # the first build also extracts the FMUs
    return timed(build, dataclasses.replace(cfg, repeats=max(cfg.repeats, 5)))[1]


def master_steady(pt: SteadyPoint, fam: Family, step: float, rtol: float, extra: dict,
                  tolerance: float = 1e-4 / DAY) -> float:
    """E_T of the periodic orbit found by shooting (clockwork.steady)."""
    comps, links = steady_components(pt, fam, rtol)
    with _system(comps, links, master_settings(fam, step, extra), {"pendulum": ["tick_time", "tick_w", "amplitude"]}) as s:
        params = {k: dict(v) for k, (_, v) in comps.items()}
        p = pt.params
        shooter = Shooter(s.master, params, "pendulum", dict(L=p.L, g=p.g))
        a_min = 0.0 if pt.chronometer else p.phi_r
        st = find_steady_state(shooter, pt.guess, a_min, tolerance=tolerance)
    if st.stalled:
        raise SimulationError(f"stalled: {st.reason}")
    return st.E_T


def master_long_run(pt: SteadyPoint, fam: Family, step: float, rtol: float, change_tol: float,
                    max_periods: int) -> tuple[float, int]:
    """Plain run from the energy-balance amplitude at rest until the period
    changes by less than change_tol (relative) from one period to the next.
    Returns (E_T of the last period, periods run)."""
    comps, links = steady_components(pt, fam, rtol, start={"phi_start": pt.guess, "w_start": 0.0})
    T0 = pt.params.T0
    with _system(comps, links, master_settings(fam, step, {}), {"pendulum": ["tick_time"]}) as s:
        m = s.master
        port = m.ports["pendulum"]
        i_tick = port.out_names.index("tick_time")
        out = port.out
        ticks = []
        last = out[i_tick]
        prev_T = None
        while len(ticks) < max_periods + 1:
            m.step(step)
            tt = out[i_tick]
            if tt != last:
                last = tt
                ticks.append(tt)
                if len(ticks) >= 2:
                    T = ticks[-1] - ticks[-2]
                    if prev_T is not None and abs(T - prev_T) / T0 < change_tol:
                        return T / T0 - 1.0, len(ticks) - 1
                    prev_T = T
            if m.t > (max_periods + 3) * 2 * T0:
                break
    raise SimulationError(f"no convergence to {change_tol * DAY:g} s/day within {len(ticks) - 1} periods")


def scipy_long_run(pt: SteadyPoint, rtol: float, change_tol: float, max_periods: int) -> tuple[float, int]:
    """The plain long run of master_long_run, monolithic: (E_T, periods)."""
    T0 = pt.params.T0
    r = None
    ticks = np.empty(0)
    while len(ticks) < max_periods + 1:
        if r is None:
            r = reference.simulate(pt.params, pt.guess, 0.0, 50 * T0, rtol=rtol, atol=atol(rtol))
        else:
            r = reference.simulate(pt.params, r.y[0], r.y[1], r.t + 50 * T0, t0=r.t, mode=r.mode, rtol=rtol,
                                   atol=atol(rtol))
        ticks = np.concatenate([ticks, r.ticks])
        T = np.diff(ticks)
        change = np.abs(np.diff(T)) / T0
        hit = np.nonzero(change < change_tol)[0]
        if hit.size:
            k = hit[0] + 1
            return T[k] / T0 - 1.0, k + 1
    raise SimulationError(f"no convergence to {change_tol * DAY:g} s/day within {len(ticks) - 1} periods")


def master_hoyng(h: Hoyng, fam: Family, step: float, rtol: float, extra: dict) -> float:
    """Time (s) of tick number h.ticks."""
    pend = dict(L=1.0, g=1.0, m=1.0, Q=0.0 if fam.split else h.Q, phi_start=0.0, w_start=h.lam0,
                rtol=rtol, atol=atol(rtol))
    comps = {"pendulum": ("Pendulum", pend),
             "escapement": ("GrasshopperEscapement", dict(torque=h.mu0, phi_r=h.phi0))}
    links = list(GRASSHOPPER_LINKS)
    if fam.split:
        comps["drag"] = ("Drag", {"c1": 1.0 / h.Q})  # m L^2 omega0 / Q with m = L = omega0 = 1
        links += DRAG_LINKS
    with _system(comps, links, master_settings(fam, step, extra), {"pendulum": ["tick_time"]}) as s:
        m = s.master
        on_point = Recorder(m, [], ticks_of="pendulum")
        ticks = on_point.ticks
        m.run_until(h.t_jump, on_point)
        s.instances["escapement"].set_values({"torque": h.mu1})
        m.discontinuity()
        t = m.t
        while len(ticks) < h.ticks:
            t += TWO_PI
            m.run_until(t, on_point)
            if t > 2.0 * h.ticks * TWO_PI:
                raise SimulationError(f"only {len(ticks)} ticks in {t:g} s")
    return ticks[h.ticks - 1]


def master_chaos(c: Chaos, fam: Family, step: float, rtol: float, extra: dict, dphi: float = 0.0) -> dict:
    vib = dict(c.vibration(), inertia=1.0, rtol=rtol, atol=atol(rtol))
    comps = {"pendulum": ("Pendulum", dict(L=1.0, m=1.0, g=9.81, Q=c.Q, phi_start=c.phi_start + dphi, w_start=0.0,
                                           rtol=rtol, atol=atol(rtol))),
             "escapement": ("GrasshopperEscapement", dict(torque=c.torque, phi_r=2 * DEG)),
             "vibration": ("MechanismVibration", vib)}
    links = GRASSHOPPER_LINKS + VIBRATION_LINKS
    t_grid = c.grid()
    a2, a2dot = np.empty(len(t_grid)), np.empty(len(t_grid))
    ticks = []
    with _system(comps, links, master_settings(fam, step, extra),
                 {"pendulum": ["tick_time"], "vibration": ["a2", "a2dot"]}) as s:
        m = s.master
        pp, vp = m.ports["pendulum"], m.ports["vibration"]
        i_tick, i_a2, i_v2 = (pp.out_names.index("tick_time"), vp.out_names.index("a2"),
                              vp.out_names.index("a2dot"))
        last = pp.out[i_tick]
        a2[0], a2dot[0] = vp.out[i_a2], vp.out[i_v2]
        for k in range(1, len(t_grid)):  # a sample interval is far shorter than a period: one tick at most
            m.run_until(t_grid[k])
            a2[k], a2dot[k] = vp.out[i_a2], vp.out[i_v2]
            tt = pp.out[i_tick]
            if tt != last:
                last = tt
                ticks.append(tt)
    stats = c.statistics(ticks, t_grid, a2)
    stats["a2_series"], stats["a2dot_series"] = a2, a2dot
    return stats


def try_row(row: Row, fn, cfg: BenchConfig):
    """Run fn timed into row; a failure is the row's status."""
    try:
        res, wall, n = timed(fn, cfg)
    except SimulationError as e:
        row.status = f"failed: {' '.join(str(e).split())[:200]}"
        return None
    except Exception as e:  # noqa: BLE001  (a benchmark row reports any failure)
        row.status = f"failed: {type(e).__name__}: {' '.join(str(e).split())[:200]}"
        return None
    row.wall_s, row.repeats = wall, n
    return res
