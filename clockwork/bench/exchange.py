"""The Model Exchange problem: the clock's pendulum as a Model Exchange FMU.

The free damped pendulum (L = 1 m, g = 9.81, Q = 1000, from 6 deg) of
tests/me_models/MePendulum, a test FMU (build/test-fmus/, or
$CW_TEST_FMU_DIR), whose ticks are state events. The error is that of the
time of its N-th tick against scipy (DOP853 at rtol 1e-13 with the
crossing located) on the same equations. Rows: clockwork's Model Exchange
wrapper with each solver; fmpy's own Model Exchange loop with CVode (the
same SUNDIALS, fmpy's root finding and output grid, in this process); and
the Co-Simulation Pendulum, which integrates the same equations with the
same pairs inside the FMU. All run from the same 1 s communication or
output grid.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from ..engine.settings import MasterSettings
from ..engine.system import System
from .config import BenchConfig, DEG, ROOT, Row, atol, timed

PROBLEM = "model_exchange"
PARAMS = {"L": 1.0, "m": 1.0, "g": 9.81, "Q": 1000.0, "phi_start": 6 * DEG}
STEP = 1.0  # s, the communication step of every row (and fmpy's output interval)
SOLVERS = {"dp54": "DP5(4)", "dop853": "DOP853", "cvode": "CVode BDF"}


def me_fmu() -> Path:
    folder = os.environ.get("CW_TEST_FMU_DIR") or ROOT / "build" / "test-fmus"
    return Path(folder) / "MePendulum.fmu"


def reference_ticks(n: int) -> np.ndarray:
    """The first n tick times (upward zero crossings of phi), s, by scipy at rtol 1e-13."""
    from scipy.integrate import solve_ivp

    L, g, Q = PARAMS["L"], PARAMS["g"], PARAMS["Q"]
    damping = math.sqrt(g / L) / Q

    def f(t, y):
        return [y[1], -(g / L) * math.sin(y[0]) - damping * y[1]]

    def tick(t, y):
        return y[0]

    tick.direction = 1.0
    T0 = 2 * math.pi * math.sqrt(L / g)
    sol = solve_ivp(f, (0.0, (n + 1.5) * T0), [PARAMS["phi_start"], 0.0], method="DOP853", rtol=1e-13,
                    atol=1e-15, events=tick)
    return sol.t_events[0][:n]


def _clockwork(path: Path, params: dict, settings: MasterSettings, t_end: float) -> tuple[float, int, dict]:
    with System({"pendulum": (str(path), params)}, [], settings, record={"pendulum": ["tick_time"]}) as s:
        s.master.run_until(t_end)
        inst = s.instances["pendulum"]
        stats = vars(s.master.stats).get("model_exchange", {}).get("pendulum", {})
        return s.output("pendulum", "tick_time"), inst.get_values(["tick_count"])[0], stats


def _fmpy(path: Path, rtol: float, t_end: float) -> tuple[float, int]:
    import fmpy

    res = fmpy.simulate_fmu(str(path), fmi_type="ModelExchange", solver="CVode", relative_tolerance=rtol,
                            stop_time=t_end, output_interval=STEP, start_values=dict(PARAMS),
                            output=["tick_time", "tick_count"])
    return float(res["tick_time"][-1]), int(res["tick_count"][-1])


def bench_model_exchange(cfg: BenchConfig, log) -> tuple[list[Row], dict]:
    n = cfg.me_ticks
    ref = reference_ticks(n)
    t_end = float(ref[-1]) + 0.5  # a quarter period past the N-th tick: the tick outputs hold it
    info = {"ticks": n, "tick_s": float(ref[-1]), "fmu": str(me_fmu())}
    rows: list[Row] = []
    path = me_fmu()

    def add(row: Row, run) -> None:
        rows.append(row)
        if not path.is_file() and row.family != "Co-Simulation Pendulum (its own pair inside)":
            row.status = f"not run: {path} is missing (cmake --build build builds the test FMUs)"
            log(row)
            return
        try:
            (t_tick, count, *rest), row.wall_s, row.repeats = timed(run, cfg)
        except Exception as e:  # noqa: BLE001 (a failed run is a row, not a crash)
            row.status = f"failed: {type(e).__name__}: {e}"
            log(row)
            return
        if count != n:
            row.status = f"{count} ticks, expected {n}"
        row.error = abs(t_tick - ref[-1])
        if rest and rest[0]:
            s = rest[0]
            row.note = (f"{s['solver']}: {s['steps']} steps, {s['rejected']} rejected, {s['rhs']} right-hand sides, "
                        f"{s['state_events']} state events, {s['event_iterations']} location trials")
        log(row)

    for rtol in cfg.me_rtols:
        for solver in cfg.me_solvers:
            settings = MasterSettings(step=STEP, tolerance=rtol, me_solver=solver)
            add(Row(PROBLEM, f"clockwork Model Exchange, {SOLVERS[solver]}", "clockwork",
                    f"h = {STEP:g} s, rtol = {rtol:.0e}", unit="s", step_s=STEP, rtol=rtol),
                lambda settings=settings: _clockwork(path, dict(PARAMS), settings, t_end))
        add(Row(PROBLEM, "fmpy Model Exchange, CVode", "fmpy", f"output interval {STEP:g} s, rtol = {rtol:.0e}",
                unit="s", step_s=STEP, rtol=rtol, note="fmpy.simulate_fmu(fmi_type='ModelExchange', solver='CVode')"),
            lambda rtol=rtol: _fmpy(path, rtol, t_end))
        cs = dict(PARAMS, rtol=rtol, atol=atol(rtol), integrator=2)
        add(Row(PROBLEM, "Co-Simulation Pendulum (its own pair inside)", "clockwork",
                f"h = {STEP:g} s, rtol = {rtol:.0e}, DOP853", unit="s", step_s=STEP, rtol=rtol),
            lambda cs=cs: _clockwork("Pendulum", cs, MasterSettings(step=STEP), t_end)[:2])
    return rows, info
