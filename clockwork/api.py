"""``clockwork.simulate``: fmpy's ``simulate_fmu`` call, for an FMU, an SSP
or a scene file (docs/fmpy-migration.md).

It loads the file as ``clockwork run`` does (an FMU alone with its
DefaultExperiment, an SSP, a scene), applies the arguments as ``--set``
would, runs one time series and returns a NumPy structured array whose
first field is ``time``: the recorded outputs, named as fmpy names them
(the variable alone for one FMU, ``instance.variable`` for a system), one
row per communication point. fmpy's arguments that have a counterpart map
to it; the others are accepted at fmpy's default value only, and any other
value is refused in one line that names the argument.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import numbers
import os
from pathlib import Path

import numpy as np

from .analyses.time_series import time_series
from .engine.description import variables as variables_of
from .engine.names import split_ref
from .engine.settings import MasterSettings
from .errors import ParametersRefused, SceneError, UsageError
from .run.catalog import load_scene
from .scene.inputs import Inputs, make_samples, sample_value, targets
from .scene.save import toml_value

# fmpy.simulate_fmu's arguments that clockwork has no counterpart for, with
# fmpy's defaults (fmpy 0.3.32): accepted at these values, refused at others.
FMPY_ONLY = {
    "validate": True, "solver": "CVode", "record_events": True, "fmi_type": None,
    "apply_default_start_values": False, "timeout": None, "debug_logging": False, "visible": False,
    "logger": None, "fmi_call_logger": None, "step_finished": None, "model_description": None,
    "fmu_instance": None, "set_input_derivatives": False, "remote_platform": "auto",
    "early_return_allowed": False, "use_event_mode": False, "initialize": True, "terminate": True,
    "fmu_state": None, "set_stop_time": True,
}
# Why each is refused: what to do instead.
_INSTEAD = {
    "solver": "it is for Model Exchange FMUs",
    "fmi_type": "clockwork co-simulates the FMU's Co-Simulation interface",
    "validate": "clockwork always checks the FMU and the values given",
    "timeout": "stop the run with Ctrl-C or a signal",
    "set_input_derivatives": "master={'extrapolation': 1} hands input polynomials to FMUs that take them",
    "early_return_allowed": "master={'early_return': ...} sets it",
}

# FMI types of recorded columns -> NumPy types (fmpy's: Enumeration as Integer in FMI 2.0, Int64 in 3.0).
_DTYPES = {"Real": np.float64, "Float64": np.float64, "Float32": np.float32, "Integer": np.int32,
           "Int32": np.int32, "Int8": np.int8, "UInt8": np.uint8, "Int16": np.int16, "UInt16": np.uint16,
           "UInt32": np.uint32, "Int64": np.int64, "UInt64": np.uint64, "Boolean": np.bool_,
           "String": object, "Binary": object}


def _number(name: str, value, positive: bool = False):
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(float(value)):
        raise UsageError(f"simulate({name}={value!r}): expected a finite number (s) or None")
    if positive and not float(value) > 0:
        raise UsageError(f"simulate({name}={value!r}): expected a number > 0")
    return float(value)


def _plain(value):
    """NumPy scalars as Python's own numbers (their repr is not TOML)."""
    return value.item() if isinstance(value, np.generic) else value


def simulate(filename, start_time=None, stop_time=None, step_size=None, relative_tolerance=None,
             output_interval=None, start_values={}, input=None, output=None, *, master=None,  # noqa: B006 (fmpy's)
             progress: bool = False, **fmpy_only):
    """Simulate an FMU, an SSP/SSD or a scene file; a structured array with
    `time` first and a field per recorded output.

    Arguments as ``fmpy.simulate_fmu``'s: `start_time`, `stop_time` (s;
    None: the DefaultExperiment's, else 0 and start + 1), `step_size` (the
    master's communication step, s; None: `output_interval`, else the
    DefaultExperiment's step, else fmpy's choice), `relative_tolerance`
    (passed to every FMU), `output_interval` (s: the step when no
    `step_size` is given, as fmpy's Co-Simulation uses it, else how often
    to record), `start_values` ({variable: value}, "instance.variable" in a
    system; a string may carry a unit, "0.4 N.cm"), `input` (fmpy's
    structured array with `time` first, or the path of a CSV input file),
    `output` (the variables to record; None: every output). clockwork's
    own: `master` (MasterSettings, or a dict of its fields: those given
    apply, a MasterSettings' fields that differ from the defaults) and
    `progress` (a progress bar). fmpy's other arguments are accepted at
    their defaults only.

    Raises UsageError/SceneError for bad input, SimulationError for a run
    that fails. An FMU that ends the simulation ends the result there.
    """
    if not isinstance(filename, (str, os.PathLike)):
        raise UsageError(f"simulate(filename={filename!r}): expected the path of an .fmu, .ssp, .ssd or .toml file")
    for name, value in fmpy_only.items():
        if name not in FMPY_ONLY:
            raise UsageError(f"simulate() got an unexpected argument {name}= (neither clockwork's nor fmpy's)")
        default = FMPY_ONLY[name]
        if value is default or (type(value) is type(default) and value == default) or (
                name == "fmi_type" and value == "CoSimulation"):
            continue
        why = _INSTEAD.get(name, "fmpy's option has no counterpart in clockwork")
        raise UsageError(f"simulate({name}={value!r}): not supported ({why}); leave it out, or give "
                         f"fmpy's default {default!r}")
    start_time = _number("start_time", start_time)
    stop_time = _number("stop_time", stop_time)
    step_size = _number("step_size", step_size, positive=True)
    relative_tolerance = _number("relative_tolerance", relative_tolerance, positive=True)
    output_interval = _number("output_interval", output_interval, positive=True)
    if not isinstance(start_values, dict) or not all(isinstance(k, str) for k in start_values):
        raise UsageError("simulate(start_values=...): expected a dict {variable name: value}")
    if output is not None and (isinstance(output, str) or not all(isinstance(o, str) for o in output)):
        raise UsageError(f"simulate(output={output!r}): expected a list of variable names")
    if not isinstance(progress, bool):
        raise UsageError(f"simulate(progress={progress!r}): expected True or False")
    settings = _master_values(master)
    if step_size is not None and "step" in settings:
        raise UsageError("simulate(): step_size and master's step both given: expected one of them")

    overrides = [f"experiment.{k}={toml_value(v)}" for k, v in (("start", start_time), ("stop", stop_time))
                 if v is not None]
    if step_size is None and "step" not in settings and output_interval is not None:
        step_size, output_interval = output_interval, None  # fmpy's Co-Simulation steps at its output interval
    if step_size is not None:
        settings["step"] = step_size
    if relative_tolerance is not None:
        settings["tolerance"] = relative_tolerance
    overrides += [f"master.{k}={toml_value(v)}" for k, v in settings.items()]
    if output_interval is not None:
        overrides.append(f"record.interval={toml_value(output_interval)}")
    overrides += [f"{k}={toml_value(_plain(v))}" for k, v in start_values.items()]
    path_input = input if isinstance(input, (str, os.PathLike)) else None
    if input is not None and path_input is None and not _is_structured(input):
        raise UsageError("simulate(input=...): expected fmpy's structured array (time first, then a field per "
                         "input) or the path of a CSV input file")
    scene = load_scene(filename, overrides, path_input)
    only = next(iter(scene.components)) if len(scene.components) == 1 else None
    if output is not None:  # one FMU: its variables by their own names, as fmpy names them
        own = variables_of(scene.components[only].model_description) if only is not None else {}
        names = [f"{only}.{o}" if o in own else o for o in output]
        scene = load_scene(filename, overrides + [f"record.outputs={toml_value(names)}"], path_input)
    if scene.sweep is not None:
        raise UsageError(f"simulate({Path(filename).name}): the scene has a sweep of {len(scene.points())} points; "
                         "simulate() runs one (give a scene without [sweep], or run it with `clockwork run`)")
    if input is not None and path_input is None:
        scene = dataclasses.replace(scene, inputs=_array_inputs(input, scene))
    try:
        result = time_series(scene, {}, progress=progress)
    except ParametersRefused as e:  # the values given, not the run, are at fault
        raise SceneError(e.message, scene.path, f"start_values ({e.instance})") from None
    return _structured(scene, result.get("series") or {"time": []}, only)


def _master_values(master) -> dict:
    if master is None:
        return {}
    if isinstance(master, MasterSettings):
        default = MasterSettings()
        return {f.name: getattr(master, f.name) for f in dataclasses.fields(master)
                if getattr(master, f.name) != getattr(default, f.name) and getattr(master, f.name) is not None}
    if isinstance(master, dict) and all(isinstance(k, str) for k in master):
        return {k: _plain(v) for k, v in master.items()}
    raise UsageError(f"simulate(master={master!r}): expected a MasterSettings or a dict of its fields")


def _is_structured(x) -> bool:
    return isinstance(x, np.ndarray) and x.dtype.names is not None and x.ndim == 1


def _array_inputs(signals: np.ndarray, scene) -> Inputs:
    """fmpy's input array as the scene's input samples, checked as an input file is."""
    names = list(signals.dtype.names)
    if names[0] != "time":
        raise UsageError(f"simulate(input=...): the first field is {names[0]!r}: expected time (fmpy's layout)")

    def fail(_line, column, detail):
        field = f" field {names[column]!r}" if column is not None else ""
        return UsageError(f"simulate(input=...):{field}: {detail}")

    connected = {(c.dst_instance, c.dst_var) for c in scene.connections}
    given = {(n, p) for n, c in scene.components.items() for p in c.parameters}
    bound = targets(names, scene.components, connected, given, fail)
    times = [float(t) for t in signals["time"]]
    cols = []
    for j, (inst, var, v) in enumerate(bound, start=1):
        column = []
        for k, x in enumerate(signals[names[j]]):
            try:
                column.append(sample_value(_plain(x), v))
            except ValueError as e:
                raise fail(None, j, f"row {k}: {e}, got {x!r}") from None
        cols.append(column)
    samples = make_samples(times, cols, bound)
    digest = hashlib.sha256(signals.tobytes() + repr(signals.dtype).encode()).hexdigest()
    return Inputs(None, digest, samples)


def _structured(scene, series: dict, only: str | None) -> np.ndarray:
    """The recorded columns as fmpy's result: a structured array, `time`
    first; an FMI 3.0 array recorded whole and in order is one field of the
    array's shape (fmpy's ``y`` of shape (3,)), else one field per element."""
    fields = [("time", np.float64)]
    data = [np.asarray(series.get("time", []), dtype=np.float64)]
    found = {n: variables_of(c.model_description) for n, c in scene.components.items()}
    columns = []  # (label, dtype, values, the element's array variable or None, its index, its instance)
    for name, values in series.items():
        if name == "time":
            continue
        inst, var = split_ref(name, found)
        v = scene.components[inst].variable(var)
        dtype = _DTYPES.get(v.type, np.float64)
        if v.type == "Enumeration":
            dtype = np.int64 if scene.components[inst].model_description.fmiVersion.startswith("3") else np.int32
        label = var if only is not None and var != "time" else name
        columns.append((label, dtype, values, getattr(v, "array", None), getattr(v, "index", 0), inst))
    k = 0
    while k < len(columns):
        label, dtype, values, array, _, inst = columns[k]
        size = math.prod(array.shape) if array is not None else 1
        run = columns[k:k + size]
        whole = (array is not None and len(run) == size and dtype is not object
                 and all(c[3] is array and c[4] == j and c[5] == inst for j, c in enumerate(run)))
        if whole:
            base = array.name if only is not None else f"{inst}.{array.name}"
            fields.append((base, dtype, tuple(array.shape)))
            data.append(np.stack([np.asarray(c[2], dtype=dtype) for c in run], axis=-1)
                        .reshape((-1, *array.shape)))
            k += size
            continue
        fields.append((label, dtype))
        data.append(np.asarray(values, dtype=dtype) if dtype is not object else np.asarray(values, dtype=object))
        k += 1
    out = np.empty(len(data[0]), dtype=fields)
    for field, column in zip(fields, data):
        out[field[0]] = column
    return out
