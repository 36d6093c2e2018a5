"""The basic analyses: a run from start to stop.

- ``time_series``: co-simulate from start to stop, record outputs (and tick
  times) at communication points.
- ``ticks``: the same, but keep only the pendulum's tick times and rates.

A grasshopper clock whose swing no longer reaches phi_r has stalled: that
is a result (``"stalled": true``), not an error. Nor is an FMU that ends the
simulation (FMI 2.0 fmi2Discard with fmi2Terminated, FMI 3.0
terminateSimulation): the run stops at the last communication point, what
was recorded is kept, and the result says when and which FMU (``"ended"``).
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..engine.recording import Recorder
from ..errors import SimulationError
from ..scene.model import SPAN_RESOLUTION
from .bounds import MAX_KEPT_VALUES
from .context import build_system, experiment, find_component, parameters, series_sink
from .registry import register


# Every key of a time_series result (t_end_s and engine always; the others when
# ticks are recorded, an FMU ends the run, or from the grasshopper clock's stall check).
COLUMNS = {"t_end_s", "engine", "engine_reason", "ended", "notes", "ticks", "mean_period_s", "last_period_s",
           "stalled", "last_amplitude_deg", "reason", "clock_ticks", "clocked"}


def series_columns(scene) -> set[str]:
    """The Recorder's columns: time and each recorded "instance.variable" (no series without outputs)."""
    return {"time", *(f"{i}.{v}" for i, v in scene.record.outputs)} if scene.record.outputs else set()


@register("ticks", columns=COLUMNS, series=set())
def ticks(scene, point: dict, progress: bool = False) -> dict:
    return time_series(scene, point, progress=progress, ticks_only=True)


@register("time_series", columns=COLUMNS, series=series_columns)
def time_series(scene, point: dict, progress: bool = False, ticks_only: bool = False, times: bool = False) -> dict:
    """Run the scene once, recording its outputs; `times`: the series has
    its time column even with nothing else recorded (clockwork.simulate's
    result, as fmpy's, has a row per communication point)."""
    start, stop = experiment(scene, point)
    outputs = [] if ticks_only else list(scene.record.outputs)
    record: dict[str, list[str]] = {}
    for inst, var in outputs:
        record.setdefault(inst, []).append(var)
    tick_inst = scene.record.ticks or (find_component(scene, "Pendulum") if ticks_only else None)
    if tick_inst:
        record.setdefault(tick_inst, []).append("tick_time")
    system = build_system(scene, point, record=record)
    with system:
        m = system.master
        # Rows at events off the grid are kept too: what no check before the run counts is bounded here.
        recorder = Recorder(m, outputs, scene.record.interval, tick_inst, times=times, limit=MAX_KEPT_VALUES)
        make_sink = series_sink() if (outputs or times) else None
        if make_sink is not None:  # written as the run goes (run.scene_run): no bound on memory to keep
            recorder.stream_to(make_sink(recorder.names, recorder.text_names))
        try:
            recorder.start()
            run_with_progress(m, stop, recorder, progress, label=scene.path.stem)
            if times:  # clockwork.simulate: the last row is the end, as fmpy's (record.interval may skip it)
                recorder.finish()
        except SimulationError as e:
            # A failed run keeps its history: what was recorded until the
            # last good communication point goes with the error (run.points).
            try:
                keep_history(e, "ticks" if ticks_only else "time_series", recorder, m, outputs, tick_inst)
            except BaseException:
                recorder.abort()
                raise
            raise
        except BaseException:  # interrupted, a full disk: nothing of the series is kept
            recorder.abort()
            raise
        try:
            series = recorder.series() if (outputs or times) else None
        except BaseException:
            recorder.abort()
            raise
        stats = vars(m.stats).copy()
        stall = _stall_check(scene, point, system) if m.ended is None else None
        ended, t_end = m.ended, m.t
        engine = {"engine": m.engine, **({"engine_reason": m.engine_reason} if m.engine_reason else {})}
        notes = list(m.notes)
        clocks = _clock_records(m)
    ticks = recorder.ticks
    result: dict = {"t_end_s": t_end if ended is not None else stop, **engine}
    if ended is not None:
        # An FMU ended the simulation: a clean end, with the results up to then.
        result["ended"] = {"instance": ended.instance, "time_s": ended.fmu_time, "last_point_s": ended.time,
                           "message": ended.message}
    if notes:
        result["notes"] = notes
    if stall is not None:
        result.update(stall)
    result.update(clocks)
    if tick_inst:  # none is a count too: a plot of it is not a plot of a missing column
        result["ticks"] = len(ticks)
    if ticks:
        t = np.asarray(ticks)
        if len(t) > 1:
            periods = np.diff(t)
            result["mean_period_s"] = float(periods.mean())
            result["last_period_s"] = float(periods[-1])
    out = {"kind": "ticks" if ticks_only else "time_series", "result": result, "statistics": stats}
    if outputs or times:
        out["series"] = series
    if tick_inst:
        out["ticks"] = ticks
    return out


def _clock_records(master) -> dict:
    """FMI 3.0 clocks (engine/clocks.py): each clock's tick times
    (``clock_ticks``) and each clocked output's values after its ticks
    (``clocked``: times and values), apart from the communication points'
    series; nothing for a scene without clocks."""
    ticks = getattr(master, "clock_ticks", None)
    if ticks is None:
        return {}
    return {"clock_ticks": {n: list(t) for n, t in ticks.items()},
            "clocked": {n: {"time": [t for t, _ in v], "value": [x for _, x in v]}
                        for n, v in master.clocked_values.items()}}


def keep_history(e: SimulationError, kind: str, recorder: Recorder, master, outputs, tick_inst) -> None:
    """Give a failed run's error what the run recorded (``e.history``: the
    data of a result without its "result", the series up to the last good
    communication point) and where it stopped (``e.last_point``, s)."""
    last = getattr(e, "last_point", None)
    if last is None:  # a failed step (or call) leaves the master at its last good point
        last = master.t
    e.last_point = last
    history: dict = {"kind": kind, "statistics": vars(master.stats).copy(), "engine": master.engine}
    if outputs:
        history["series"] = recorder.series()
    if tick_inst:
        history["ticks"] = recorder.ticks
    e.history = history


PROGRESS_DELAY_S = 1.0  # a run shorter than this shows no bar


def run_with_progress(master, stop: float, on_point, progress: bool, label: str) -> None:
    span = stop - master.t
    step = master.settings.step
    # Chunks end on grid points, computed as run_until computes them
    # (start + k * step): an end an ulp short of one would cut a step there.
    per_chunk = max(1, round(span / 200.0 / step))
    origin = master.start_time
    k = math.floor((master.t - origin) / step + 1e-9)
    t0 = master.t
    bar = None
    began = time.perf_counter()
    try:
        while master.t < stop - SPAN_RESOLUTION * max(1.0, abs(stop)) and master.ended is None:
            k += per_chunk
            master.run_until(min(stop, origin + k * step), on_point)
            if bar is None and progress and time.perf_counter() - began >= PROGRESS_DELAY_S:
                # Made (and tqdm imported) only once the run outlasts the delay: start-up time.
                from tqdm import tqdm

                bar = tqdm(total=span, desc=label, unit="s sim",
                           bar_format="{l_bar}{bar}| {n:.4g}/{total:.4g} s [{elapsed}<{remaining}]")
            if bar is not None:
                bar.update(master.t - t0 - bar.n)
    finally:
        if bar is not None:
            bar.close()


def _stall_check(scene, point: dict, system) -> dict | None:
    """A grasshopper clock whose swing ended below phi_r has stalled: a result.

    The relay never switches again, so the pendulum settles; the last
    turning-point amplitude tells.
    """
    pendulum = find_component(scene, "Pendulum")
    escapement = find_component(scene, "GrasshopperEscapement")
    if pendulum is None or escapement is None:
        return None
    params = parameters(scene, point)
    phi_r = params[escapement]["phi_r"]
    amplitude = system.value(pendulum, "amplitude")
    turns = system.instances[pendulum].get_integer(["turn_count"])[0]
    if turns == 0:
        # No turning point yet: a stall only if a whole small-swing period went by without one.
        start, _ = experiment(scene, point)
        period_s = 2.0 * math.pi * math.sqrt(params[pendulum]["L"] / params[pendulum]["g"])
        if system.master.t - start < period_s:
            return {"stalled": False, "last_amplitude_deg": None}
    stalled = turns == 0 or amplitude <= phi_r
    out = {"stalled": stalled, "last_amplitude_deg": math.degrees(amplitude)}
    if stalled:
        out["reason"] = (f"the swing ({math.degrees(amplitude):.4g} deg at the last turning point) "
                         f"no longer reaches phi_r = {math.degrees(phi_r):.4g} deg")
    return out
