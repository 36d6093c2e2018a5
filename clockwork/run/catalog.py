"""Scene files checked against every analysis and plot kind there is.

``load_scene`` is clockwork.scene.load_scene with the kinds that the
analyses and the plots register (importing them registers them all).
"""

from __future__ import annotations

import bisect
import difflib
import math
import os
from pathlib import Path

from ..analyses import registry as analyses
from ..analyses.bounds import BYTES_PER_VALUE
from ..analyses.bounds import MAX_KEPT_VALUES as MAX_RECORDED_VALUES
from ..analyses.bounds import check_bounds
from ..fmi.description import array_size
from ..fmi.description import variables as variables_of
from ..engine.instances import make_instance
from ..errors import ParametersRefused, SceneError, SimulationError
from ..paths import scenarios_dir
from ..results.plots import registry as plots
from ..scene import Kinds
from ..scene import load_scene as _load_scene


def kinds() -> Kinds:
    return Kinds(analyses.ANALYSIS_KEYS, analyses._ANALYSIS_CONVERT, plots.PLOT_KEYS, plots._PLOT_CONVERT)


def find_scene(spec: str | os.PathLike) -> Path:
    """A scene file: a path, or the name of a bundled scene ("ziemkiewicz_fig4a")."""
    path = Path(spec)
    if path.exists() or path.suffix or len(path.parts) != 1 or not str(spec).strip():
        return path
    bundled = scenarios_dir() / f"{spec}.toml"
    if bundled.is_file():
        return bundled
    known = sorted(f.stem for f in scenarios_dir().glob("*.toml"))
    close = difflib.get_close_matches(str(spec), known, n=1)
    hint = f" (did you mean {close[0]}?)" if close else ""
    raise SceneError(f"no such scene file, and no bundled scene of that name{hint}; "
                     "`clockwork list` shows the bundled scenes", path)


def load_scene(path: str | os.PathLike, overrides=(), input_file: str | os.PathLike | None = None,
               streamed: bool = False):
    """Load, override and validate a scene file (or a bundled scene by name,
    an SSP, an FMU), with an input file when given; raises SceneError.
    `streamed`: a single run's series will be written as the run goes
    (run_scene), so the bound on recorded values in memory leaves it out
    (run_scene checks the disk space instead)."""
    scene = _load_scene(find_scene(path), overrides, kinds(), input_file)
    try:
        analyses.check_analysis(scene)
        check_recording_bound(scene, streamed)
        check_plot_axes(scene)
    except SceneError as e:  # named by where the value came from (--set, an FMU's DefaultExperiment...)
        raise scene.refused_at(e) from None
    return scene


def check_loadable(scene) -> None:
    """Load and instantiate each FMU once, as a run does before its first
    step, and free it: a binary that does not load (a PIE executable, a
    missing dependency) or refuses its model description's GUID is refused
    by `validate` too, under the component's key."""
    for name, c in scene.components.items():
        inst = make_instance(name, c.fmu_path, c.model_description, interface=c.interface)
        inst.label = c.fmu_label or None
        try:
            inst.instantiate()
        except SceneError as e:  # nothing instantiated: nothing to free
            if Path(scene.path).suffix.lower() == ".toml":
                raise SceneError(e.detail, scene.path, f"components.{name}.fmu") from None
            # an FMU alone or an SSP's component: the line names the FMU (an archive's member), which has no
            # scene key
            raise SceneError(e.detail) from None
        try:
            _set_values(scene, name, c, inst)
        finally:
            inst.free()


def _set_values(scene, name: str, c, inst) -> None:
    """Hand the component its values as the run does before its first step
    (fmi2SetupExperiment, then each value, then Initialization Mode: the
    instance is freed there): a value the FMU refuses to take is refused by
    `validate` too, named as the run names it (scene_run). What fails after
    the values are taken (the initialization itself, which depends on the
    inputs the wiring gives) is the run's to find."""
    if not c.parameters or c.model_exchange:
        return
    try:
        inst.setup(scene.experiment.start, c.parameters, scene.master.tolerance)
    except ParametersRefused as e:
        if "setting parameters (" not in e.message:
            return
        if Path(scene.path).suffix.lower() == ".toml":
            raise SceneError(e.message, scene.path, f"components.{name}.parameters") from None
        given = {".fmu": "--set", ".xml": "--set or the OSP file's initial values"}.get(
            Path(scene.path).suffix.lower(), "--set or the SSP's parameter values")
        raise SceneError(e.message, scene.path, f"the values {given} gave {name}") from None
    except (SimulationError, SceneError):
        return


def check_plot_axes(scene) -> None:
    """Every column a plot names is checked now, not after the run: in a
    sweep's results, "instance.variable" is a sweep axis (result columns
    have no dot) and any other name one of the columns the analysis kind
    declares; in a run's series, one of the series columns it declares."""
    axes = {f"{a}.{b}" for a, b in (ax.parameter for ax in scene.sweep.axes)} if scene.sweep else set()
    kind = (scene.analysis or {}).get("kind", "time_series")
    declared = {"rows": analyses.result_columns(scene), "series": analyses.series_columns(scene)}
    for i, spec in enumerate(scene.plots):
        keys, source = plots.PLOT_COLUMNS.get(spec["kind"], ({}, "rows"))
        if source not in declared:
            continue
        for key, default in keys.items():
            for name in plots.column_names(spec, key, default):
                if source == "rows" and "." in name:
                    if name not in axes:
                        _refuse(scene, i, key, name, "is not a sweep axis", sorted(axes),
                                f"a result column or one of the axes ({', '.join(sorted(axes)) or 'none'})")
                    continue
                known = declared[source]
                if known is not None and name not in known:
                    what = "results" if source == "rows" else "series"
                    choices = sorted(known | axes if source == "rows" else known)
                    _refuse(scene, i, key, name, f"is not a column of {kind} {what}", choices,
                            f"one of {', '.join(choices)}" if choices else f"none: {kind} has no {what} here")


def _refuse(scene, i: int, key: str, name: str, what: str, choices: list[str], expected: str) -> None:
    close = difflib.get_close_matches(name, choices, n=1)
    raise SceneError(f"{name} {what}{f' (did you mean {close[0]}?)' if close else ''}: expected {expected}",
                     scene.path, f"plot[{i}].{key}")


# What a run that records at communication points may keep in memory: each
# value is a Python float in a list (about 41 bytes at the peak, measured:
# docs/reliability.md) until the point is written.
_RECORDING_KINDS = ("time_series", "ticks")


def _recorded_columns(scene) -> int:
    """Columns the recorder keeps: time and every recorded output, an FMI 3.0
    array by its elements (each a column)."""
    n = 1
    for inst, name in scene.record.outputs:
        comp = scene.components.get(inst)
        v = variables_of(comp.model_description).get(name) if comp is not None else None
        n += array_size(v) if v is not None else 1
    return n


def _input_events(scene, start: float, stop: float) -> int:
    """Input events inside the span: each may add a row off the grid."""
    events = scene.inputs.samples.events if scene.inputs is not None else ()
    return bisect.bisect_right(events, stop) - bisect.bisect_left(events, start)


def recorded_values(scene, series: bool = True) -> tuple[int, float, float]:
    """(values a point records at most, its span s, its recording interval s),
    for the analyses that record over the whole experiment: a row of the
    recorded outputs and the time per record.interval (or communication
    step), and at most one tick per communication step. Without `series`,
    the ticks alone (a series that is streamed to disk keeps no memory)."""
    kind = (scene.analysis or {}).get("kind", "time_series")
    if kind not in _RECORDING_KINDS:
        return 0, 0.0, 0.0
    span = scene.experiment.stop - scene.experiment.start
    every = scene.record.interval or scene.master.step
    columns = _recorded_columns(scene) if scene.record.outputs and kind == "time_series" and series else 0
    ticks = scene.record.ticks is not None or kind == "ticks"
    rows = math.floor(span / every) + 1
    if not scene.record.interval:  # every point is kept: an input event's too
        rows += _input_events(scene, scene.experiment.start, scene.experiment.stop)
    n = rows * columns + (math.floor(span / scene.master.step) + 1 if ticks else 0)
    return n, span, every


def series_size(scene) -> tuple[int, int]:
    """(rows, columns with time) of a single run's series at most: what its
    files take on disk (run.scene_run checks the free space)."""
    kind = (scene.analysis or {}).get("kind", "time_series")
    if kind != "time_series" or not scene.record.outputs:
        return 0, 0
    span = scene.experiment.stop - scene.experiment.start
    rows = math.floor(span / (scene.record.interval or scene.master.step)) + 1
    if not scene.record.interval:
        rows += _input_events(scene, scene.experiment.start, scene.experiment.stop)
    return rows, _recorded_columns(scene)


def check_recording_bound(scene, streamed: bool = False) -> None:
    """Refuse, before the run, a point that would record more than
    MAX_RECORDED_VALUES in memory (e.g. stop = 1e12 s at a 0.01 s step);
    with `streamed` (a single run written as it goes), its series is on
    disk and its ticks alone count."""
    variants = [scene]
    if scene.sweep is not None and any(a.parameter[0] in ("master", "experiment", "analysis") or a.parameter[1] in ("L", "g")
                                       for a in scene.sweep.axes):
        variants = [scene.variant(p) for p in scene.points()]
    series = not streamed or scene.sweep is not None
    n, span, every = max(recorded_values(v, series) for v in variants)
    if n > MAX_RECORDED_VALUES:
        raise SceneError(f"a run of {span:g} s recording every {every:g} s keeps about {n:.3g} values in memory, "
                         f"more than {MAX_RECORDED_VALUES:.0e} (about {MAX_RECORDED_VALUES * BYTES_PER_VALUE / 1e6:.0f} "
                         "MB): "
                         "give a longer record.interval, a shorter span (experiment.stop), fewer record.outputs, "
                         "or a longer master.step", scene.path, "experiment.stop")
    kind = (scene.analysis or {}).get("kind", "time_series")
    for v in variants:  # the other kinds' memory, and every kind's steps
        check_bounds(v, kind)
