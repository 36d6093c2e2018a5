"""The three problems, each run across its families, steps and tolerances."""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from ..errors import SimulationError
from ..physics import reference
from .config import BenchConfig, DAY, DEG, Family, GRASSHOPPER_LINKS, Row, VIBRATION_LINKS, atol, row_label
from .problems import Chaos, Hoyng, SteadyPoint, TWIN_DPHI, public_stats, chaos_reference, hoyng_reference
from .masters import steady_components, try_row, master_chaos, master_hoyng, master_long_run, master_steady, scipy_long_run
from .peers import PeerRunner, tick_times, export_scene, scene_toml, tool_available


def _long_run_row(row: Row, run, pt: SteadyPoint, cfg: BenchConfig) -> None:
    """Fill a row of a plain run until the period settles: run() -> (E_T, periods)."""
    res = try_row(row, run, cfg)
    if res is not None:
        row.error = abs(res[0] - pt.E_T) * DAY
        row.note = f"{res[1]} periods from the energy-balance amplitude at rest"


def bench_steady(cfg: BenchConfig, pt: SteadyPoint, peers: PeerRunner, log) -> list[Row]:
    rows = []
    prob = pt.key
    unit = "s/day"
    tol = cfg.shooting_tolerance_s_per_day / DAY
    for fam in cfg.steady_families:
        for step, rtol, extra in fam.points:
            row = Row(prob, fam.name, "clockwork", row_label(step, rtol, extra), unit=unit, step_s=step, rtol=rtol,
                      note="periodic-orbit shooting (clockwork.steady)")
            E_T = try_row(row, lambda: master_steady(pt, fam, step, rtol, extra, tolerance=tol), cfg)
            if E_T is not None:
                row.error = abs(E_T - pt.E_T) * DAY
            rows.append(row)
            log(row)
    default = Family("plain long run")
    for ctol in cfg.long_run_tolerances:
        row = Row(prob, "plain long run (default settings)", "clockwork",
                  f"h = 0.5 s, rtol = 1e-12, until the period changes < {ctol:g} s/day", unit=unit, step_s=0.5,
                  rtol=1e-12)
        _long_run_row(row, lambda: master_long_run(pt, default, 0.5, 1e-12, ctol / DAY, cfg.long_run_max_periods),
                      pt, cfg)
        rows.append(row)
        log(row)
    for rtol in cfg.scipy_rtols:
        row = Row(prob, "scipy DOP853 shooting", "scipy", f"rtol = {rtol:.0e}", unit=unit, rtol=rtol,
                  note="reference.steady_state")
        ss = try_row(row, lambda: reference.steady_state(pt.params, rtol=rtol), cfg)
        if ss is not None:
            row.error = abs(ss.E_T - pt.E_T) * DAY
        rows.append(row)
        log(row)
    n = cfg.peer_periods
    for rtol in cfg.scipy_rtols:
        row = Row(prob, "scipy DOP853 integration", "scipy", f"rtol = {rtol:.0e}, {n} periods from the reference orbit",
                  unit=unit, rtol=rtol)

        def run():
            r = reference.simulate(pt.params, pt.ref.amplitude, 0.0, (n + 1.0) * pt.ref.period, rtol=rtol,
                                   atol=atol(rtol))
            return r.ticks

        ticks = try_row(row, run, cfg)
        if ticks is not None:
            row.error = abs((ticks[n] - ticks[0]) / n / pt.params.T0 - 1.0 - pt.E_T) * DAY
        rows.append(row)
        log(row)
    for ctol in cfg.scipy_long_run_tolerances:
        row = Row(prob, "scipy DOP853 plain long run", "scipy",
                  f"rtol = 1e-10, until the period changes < {ctol:g} s/day", unit=unit, rtol=1e-10)
        _long_run_row(row, lambda: scipy_long_run(pt, 1e-10, ctol / DAY, cfg.long_run_max_periods), pt, cfg)
        rows.append(row)
        log(row)
    if prob in cfg.peer_points:
        rows += _steady_peers(cfg, pt, peers, log)
    return rows


def _steady_peers(cfg: BenchConfig, pt: SteadyPoint, peers: PeerRunner, log) -> list[Row]:
    """Fixed-step peers, started on the reference's periodic orbit (at the right
    turning point), `peer_periods` periods: the period averaged over them."""
    rows = []
    n = cfg.peer_periods
    fam = Family("peer")
    for step in cfg.peer_steps:
        steps = math.ceil((n + 1.0) * pt.ref.period / step)
        comps, links = steady_components(pt, fam, 1e-12, start={"phi_start": pt.ref.amplitude, "w_start": 0.0})
        ssp = None
        for tool in cfg.peer_tools:
            row = Row(pt.key, f"{tool} (fixed step)", tool,
                      f"h = {step:.4g} s, FMU rtol = 1e-12, {n} periods from the reference orbit", unit="s/day",
                      step_s=step, rtol=1e-12)
            rows.append(row)
            missing = tool_available(tool)
            if missing is not None:
                row.status = missing
                log(row)
                continue
            if ssp is None:
                try:
                    ssp = export_scene(peers.work / f"{pt.key}_h{step:g}.toml",
                                       scene_toml(f"bench {pt.key}", comps, links, step, steps * step))
                except Exception as e:  # noqa: BLE001
                    row.status = f"export failed: {type(e).__name__}: {e}"
                    log(row)
                    continue
            res = peers.run(row, tool, ssp, steps, step, ["pendulum.tick_time"])
            if res is not None:
                ticks = tick_times(res["pendulum.tick_time"])
                if len(ticks) < n + 1:
                    row.status = f"only {len(ticks)} ticks"
                else:
                    row.error = abs((ticks[n] - ticks[0]) / n / pt.params.T0 - 1.0 - pt.E_T) * DAY
            log(row)
    return rows


def bench_hoyng(cfg: BenchConfig, log) -> tuple[list[Row], dict]:
    h = Hoyng(jump_periods=cfg.hoyng_jump_periods, ticks=cfg.hoyng_ticks)
    t0 = time.perf_counter()
    ref_ticks = hoyng_reference(h)
    ref_wall = time.perf_counter() - t0
    ref = float(ref_ticks[h.ticks - 1])
    check = hoyng_reference(h, rtol=1e-11)
    info = {"tick_s": ref, "wall_s": ref_wall, "rtol_1e-11_minus_1e-12_s": float(check[h.ticks - 1] - ref)}
    rows = []
    prob = "hoyng"
    for fam in cfg.hoyng_families:
        for step, rtol, extra in fam.points:
            row = Row(prob, fam.name, "clockwork", row_label(step, rtol, extra), unit="s", step_s=step, rtol=rtol)
            t = try_row(row, lambda: master_hoyng(h, fam, step, rtol, extra), cfg)
            if t is not None:
                row.error = abs(t - ref)
            rows.append(row)
            log(row)
    for rtol in cfg.hoyng_scipy_rtols:
        row = Row(prob, "scipy DOP853 integration", "scipy", f"rtol = {rtol:.0e}", unit="s", rtol=rtol)
        ticks = try_row(row, lambda: hoyng_reference(h, rtol=rtol), cfg)
        if ticks is not None:
            row.error = abs(ticks[h.ticks - 1] - ref)
        rows.append(row)
        log(row)
    for tool in cfg.peer_tools:
        rows.append(Row(prob, f"{tool} (fixed step)", tool, "-", unit="s", status="not run",
                        note="the torque jump is a parameter change during the run, which an SSP archive "
                             "cannot express"))
    return rows, info


def bench_chaos(cfg: BenchConfig, peers: PeerRunner, log) -> tuple[list[Row], dict]:
    c = Chaos(t_end=cfg.chaos_t_end, transient=cfg.chaos_transient, sample=cfg.chaos_sample)
    t0 = time.perf_counter()
    ref = chaos_reference(c)
    ref_wall = time.perf_counter() - t0
    # The statistics' own scatter: the reference from an angle 1e-6 deg larger (Z Fig. 10b).
    # The twin 1e-6 deg higher (Z Fig. 10b) gives the statistics' own scatter
    # and, with the reference, the reference's lambda2.
    other = chaos_reference(c, dphi=TWIN_DPHI)
    floor = {"rate_s_per_day": abs(other["rate_s_per_day"] - ref["rate_s_per_day"]),
             "a2_rms_relative": abs(other["a2_rms"] / ref["a2_rms"] - 1.0)}
    lambda2_ref = c.lambda2(c.grid(), ref, other)
    info = {"reference": public_stats(ref), "wall_s": ref_wall, "floor": floor, "t_end_s": c.t_end,
            "transient_s": c.transient, "lambda2_reference_per_s": lambda2_ref}
    rows = []

    def add(fam_name, tool, label, step, rtol, fn, note="", twin_fn=None):
        r1 = Row("chaos_rate", fam_name, tool, label, unit="s/day", step_s=step, rtol=rtol, note=note)
        stats = fn(r1)
        r2 = dataclasses.replace(r1, problem="chaos_a2rms", unit="relative")
        if stats is not None:
            r1.error = abs(stats["rate_s_per_day"] - ref["rate_s_per_day"])
            r2.error = abs(stats["a2_rms"] / ref["a2_rms"] - 1.0)
            r2.wall_s, r2.repeats, r2.note = r1.wall_s, r1.repeats, r1.note
        else:
            r2.status, r2.note = r1.status, r1.note
        rows.extend([r1, r2])
        if twin_fn is not None:
            # lambda2 needs the twin run too: its wall time is both runs'.
            r3 = dataclasses.replace(r1, problem="chaos_lambda2", unit="1/s", error=math.nan, wall_s=math.nan)
            if stats is not None:
                twin = twin_fn(r3)
                if twin is not None:
                    try:
                        lam = c.lambda2(c.grid(), stats, twin)
                        r3.error = abs(lam - lambda2_ref)
                        r3.note = f"lambda2 = {lam:.4g} 1/s"
                        r3.wall_s = r1.wall_s + r3.wall_s
                    except SimulationError as e:
                        r3.status = str(e)
            else:
                r3.status = r1.status
            rows.append(r3)
        log(r1)

    for fam in cfg.chaos_families:
        for step, rtol, extra in fam.points:
            add(fam.name, "clockwork", row_label(step, rtol, extra), step, rtol,
                lambda row: try_row(row, lambda: master_chaos(c, fam, step, rtol, extra), cfg),
                twin_fn=lambda row: try_row(row, lambda: master_chaos(c, fam, step, rtol, extra, TWIN_DPHI), cfg))
    for rtol in cfg.chaos_scipy_rtols:
        add("scipy DOP853 integration", "scipy", f"rtol = {rtol:.0e}", None, rtol,
            lambda row: try_row(row, lambda: chaos_reference(c, rtol=rtol), cfg),
            twin_fn=lambda row: try_row(row, lambda: chaos_reference(c, rtol=rtol, dphi=TWIN_DPHI), cfg))
    names = ["pendulum.tick_time", "vibration.a2"]
    for step in cfg.chaos_peer_steps:
        steps = round(c.t_end / step)
        comps = {"pendulum": ("Pendulum", dict(L=1.0, m=1.0, g=9.81, Q=c.Q, phi_start=c.phi_start, w_start=0.0,
                                               rtol=1e-10, atol=1e-12)),
                 "escapement": ("GrasshopperEscapement", dict(torque=c.torque, phi_r=2 * DEG)),
                 "vibration": ("MechanismVibration", dict(c.vibration(), inertia=1.0, rtol=1e-10, atol=1e-12))}
        ssp = None
        for tool in cfg.chaos_peer_tools:
            def run_one(row, tool=tool, step=step, steps=steps, comps=comps):
                nonlocal ssp
                if tool_available(tool) is not None:
                    row.status = tool_available(tool)
                    return None
                if ssp is None:
                    ssp = export_scene(peers.work / f"chaos_h{step:g}.toml",
                                       scene_toml("bench chaos", comps, GRASSHOPPER_LINKS + VIBRATION_LINKS,
                                                  step, steps * step))
                res = peers.run(row, tool, ssp, steps, step, names)
                if res is None:
                    return None
                t = np.asarray(res["time"])
                on = np.abs(t / c.sample - np.round(t / c.sample)) < 1e-6
                t_grid = np.r_[0.0, t[on]]
                a2 = np.r_[0.0, np.asarray(res["vibration.a2"])[on]]  # a2_start = 0
                try:
                    return c.statistics(tick_times(res["pendulum.tick_time"]), t_grid, a2)
                except SimulationError as e:
                    row.status = str(e)
                    return None

            add(f"{tool} (fixed step)", tool, f"h = {step:.4g} s, FMU rtol = 1e-10", step, 1e-10, run_one)
    return rows, info
