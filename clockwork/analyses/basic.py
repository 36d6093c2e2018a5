"""The basic analyses.

- ``time_series``: co-simulate from start to stop, record outputs (and tick
  times) at communication points.
- ``ticks``: the same, but keep only the pendulum's tick times and rates.
- ``steady_state``: the periodic orbit by shooting (clockwork.steady) and
  its rate errors E_T, E_C, E_E.
"""

from __future__ import annotations

import math

import numpy as np

from . import register
from .. import analytic
from ..errors import SimulationError
from ..steady import Shooter, energy_balance_amplitude, find_steady_state

ESCAPEMENTS = ("GrasshopperEscapement", "ChronometerEscapement")


def find_component(scene, model: str | tuple[str, ...]) -> str | None:
    """Name of the first component whose model is `model` (or one of them)."""
    models = (model,) if isinstance(model, str) else model
    for name, c in scene.components.items():
        if c.model_description.modelName in models:
            return name
    return None


@register("steady_state", {"tolerance_s_per_day", "max_periods", "measure_periods", "amplitude_guess"})
def steady_state(scene, point: dict, progress: bool = False) -> dict:
    from ..runner import build_system, parameters

    cfg = scene.analysis or {}
    pendulum = find_component(scene, "Pendulum")
    if pendulum is None:
        raise SimulationError("the steady_state analysis needs a Pendulum component")
    escapement = find_component(scene, ESCAPEMENTS)
    params = parameters(scene, point)
    pp = params[pendulum]
    esc_model = scene.components[escapement].model_description.modelName if escapement else None
    esc = params.get(escapement, {})
    a_min = None
    if esc_model == "GrasshopperEscapement":
        a_min = esc["phi_r"]
    elif esc_model == "ChronometerEscapement":
        a_min = max(esc["alpha_m2"], 0.0)
    guess = cfg.get("amplitude_guess") or energy_balance_amplitude(pp, esc_model, esc)
    if guess is None:
        raise SimulationError("steady_state: give analysis.amplitude_guess (no energy balance for this escapement)")
    tolerance = cfg.get("tolerance_s_per_day", 1e-3) / analytic.SECONDS_PER_DAY
    system = build_system(scene, point, record={pendulum: ["tick_time", "tick_w", "amplitude"]})
    with system:
        shooter = Shooter(system.master, params, pendulum, pp,
                          max_period_factor=float(cfg.get("max_periods", 3)))
        if guess <= 0:
            result = None
        else:
            result = find_steady_state(shooter, guess, a_min, tolerance=tolerance)
        stats = vars(system.master.stats).copy()
    if result is None:
        from ..steady import SteadyState
        result = SteadyState(stalled=True, tolerance=tolerance, reason="no driving torque")
    out = result.as_dict()
    torque = esc.get("torque") if esc else None
    out["torque_Nm"] = torque
    out["energy_balance_amplitude_deg"] = math.degrees(guess) if guess else None
    if esc_model == "GrasshopperEscapement" and not result.stalled and pp["Q"] > 0:
        out["E_E_B7_s_per_day"] = analytic.escapement_error_B7(result.amplitude, esc["phi_r"], pp["Q"]) * analytic.SECONDS_PER_DAY
    return {"kind": "steady_state", "result": out, "statistics": stats}


@register("ticks")
def ticks(scene, point: dict, progress: bool = False) -> dict:
    return time_series(scene, point, progress=progress, ticks_only=True)


@register("time_series")
def time_series(scene, point: dict, progress: bool = False, ticks_only: bool = False) -> dict:
    from ..runner import build_system, experiment

    start, stop = experiment(scene, point)
    outputs = [] if ticks_only else list(scene.record.outputs)
    record: dict[str, list[str]] = {}
    for inst, var in outputs:
        record.setdefault(inst, []).append(var)
    tick_inst = scene.record.ticks or (find_component(scene, "Pendulum") if ticks_only else None)
    if tick_inst:
        record.setdefault(tick_inst, []).append("tick_time")
    system = build_system(scene, point, record=record)
    columns: dict[str, list[float]] = {"time": []}
    for inst, var in outputs:
        columns[f"{inst}.{var}"] = []
    ticks: list[float] = []
    with system:
        m = system.master
        discrete = {(i, v) for i, v in outputs if v in m.discrete_outputs.get(i, [])}

        class _Discrete:
            """Reads an Integer/Boolean output when sampled (not per step)."""

            def __init__(self, inst, var):
                self.inst, self.var = system.instances[inst], var
                self.kind = self.inst.variables[var].type

            def __getitem__(self, _):
                return float(self.inst.get_integer([self.var])[0] if self.kind == "Integer"
                             else self.inst.get_boolean([self.var])[0])

        ports = [(_Discrete(i, v), 0) if (i, v) in discrete else (m.ports[i], m.ports[i].out_names.index(v))
                 for i, v in outputs]
        ports = [(p.out if hasattr(p, "out") else p, j) for p, j in ports]
        names = [f"{i}.{v}" for i, v in outputs]
        tick_port = m.ports[tick_inst] if tick_inst else None
        tick_pos = tick_port.out_names.index("tick_time") if tick_inst else 0
        step = m.settings.step
        interval = scene.record.interval
        stride = max(1, round(interval / step)) if interval else 1
        state = {"k": 0, "last_tick": tick_port.out[tick_pos] if tick_port else 0.0}

        def sample(master) -> None:
            if tick_port is not None:
                tt = tick_port.out[tick_pos]
                if tt != state["last_tick"] and tt > 0:
                    ticks.append(tt)
                    state["last_tick"] = tt
            if not outputs:
                return
            on_grid = abs((master.t - master.start_time) / step - round((master.t - master.start_time) / step)) < 1e-6
            if on_grid:
                state["k"] += 1
                if state["k"] % stride:
                    return
            elif interval:
                return
            columns["time"].append(master.t)
            for name, (arr, j) in zip(names, ports):
                columns[name].append(arr[j])

        if outputs:
            columns["time"].append(m.t)
            for name, (arr, j) in zip(names, ports):
                columns[name].append(arr[j])
        run_with_progress(m, stop, sample, progress, label=scene.path.stem)
        stats = vars(m.stats).copy()
        stall = _stall_check(scene, point, system)
    result: dict = {"t_end_s": stop}
    if stall is not None:
        result.update(stall)
    if ticks:
        t = np.asarray(ticks)
        result["ticks"] = len(ticks)
        if len(t) > 1:
            periods = np.diff(t)
            result["mean_period_s"] = float(periods.mean())
            result["last_period_s"] = float(periods[-1])
    out = {"kind": "ticks" if ticks_only else "time_series", "result": result, "statistics": stats}
    if outputs:
        out["series"] = columns
    if tick_inst:
        out["ticks"] = ticks
    return out


def run_with_progress(master, stop: float, on_point, progress: bool, label: str) -> None:
    from tqdm import tqdm

    span = stop - master.t
    with tqdm(total=span, disable=not progress, delay=1.0, desc=label, unit="s sim",
              bar_format="{l_bar}{bar}| {n:.4g}/{total:.4g} s [{elapsed}<{remaining}]") as bar:
        step = master.settings.step
        # Chunks are whole multiples of the step so that the grid is kept.
        chunk = step * max(1, round(span / 200.0 / step))
        t0 = master.t
        n = 0
        while master.t < stop - 1e-12 * max(1.0, abs(stop)):
            n += 1
            master.run_until(min(stop, t0 + n * chunk), on_point)
            bar.update(master.t - t0 - bar.n)


def _stall_check(scene, point: dict, system) -> dict | None:
    """A grasshopper clock whose swing ended below phi_r has stalled: a result.

    The relay never switches again, so the pendulum settles; the last
    turning-point amplitude tells.
    """
    from ..runner import parameters

    pendulum = find_component(scene, "Pendulum")
    escapement = find_component(scene, "GrasshopperEscapement")
    if pendulum is None or escapement is None:
        return None
    phi_r = parameters(scene, point)[escapement]["phi_r"]
    amplitude = system.value(pendulum, "amplitude")
    turns = system.instances[pendulum].get_integer(["turn_count"])[0]
    stalled = turns == 0 or amplitude <= phi_r
    out = {"stalled": stalled, "last_amplitude_deg": math.degrees(amplitude)}
    if stalled:
        out["reason"] = (f"the swing ({math.degrees(amplitude):.4g} deg at the last turning point) "
                         f"no longer reaches phi_r = {math.degrees(phi_r):.4g} deg")
    return out
