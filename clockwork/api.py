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
from .arguments import Choice, Either, Flag, Instance, Mapping, Optional, Real, Spec, Text, checked, fspath, show
from .arguments import Path as PathSpec
from .fmi.description import element_name
from .fmi.description import variables as variables_of
from .engine.model_exchange import interface_of
from .engine.names import split_ref
from .engine.settings import MasterSettings
from .errors import ParametersRefused, SceneError, UsageError
from .run.catalog import load_scene
from .scene.inputs import Inputs, make_samples, sample_value, targets
from .scene.load import Given

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
    "validate": "clockwork always checks the FMU and the values given",
    "timeout": "stop the run with Ctrl-C or a signal",
    "set_input_derivatives": "master={'extrapolation': 1} hands input polynomials to FMUs that take them",
    "early_return_allowed": "master={'early_return': ...} sets it",
}

# fmpy's fmi_type: the interface an FMU file is run through, as the scene's `interface` names it.
_FMI_TYPES = {"CoSimulation": "co-simulation", "ModelExchange": "model-exchange"}

# More output names than an FMU has variables: an iterator (not a list)
# that gives more is taken for an endless one (itertools.count, repeat).
MAX_OUTPUT_NAMES = 1_000_000

# FMI types of recorded columns -> NumPy types (fmpy's: Enumeration as Integer in FMI 2.0, Int64 in 3.0).
_DTYPES = {"Real": np.float64, "Float64": np.float64, "Float32": np.float32, "Integer": np.int32,
           "Int32": np.int32, "Int8": np.int8, "UInt8": np.uint8, "Int16": np.int16, "UInt16": np.uint16,
           "UInt32": np.uint32, "Int64": np.int64, "UInt64": np.uint64, "Boolean": np.bool_,
           "String": object, "Binary": object}


class _Value(Spec):
    """A value a scene file could give (TOML's kinds): a bool, a number
    (int, float, a fraction, numpy's), a string, or a list, tuple or numpy
    array of them (an FMI 3.0 array's value). What it must be beyond that
    (a Real, an Integer in range, an item of an Enumeration) the FMU's
    variable or the master setting says, when the scene is loaded."""

    what = "a number, true or false, a string, or a list or array of them"

    def accepts(self, value) -> bool:
        try:
            _toml(value)
        except ValueError:
            return False
        return True


def _toml(value, depth: int = 0):
    """`value` as TOML would give it: numpy scalars and arrays, tuples and
    fractions as Python's bool, int, float, str and list; ValueError for
    anything TOML has no kind for (None, complex, Decimal, dicts, sets,
    bytes, dates, objects), for a masked value (numpy.ma: no value, not
    its placeholder) and for a number or string whose conversion fails."""
    if isinstance(value, np.ma.MaskedArray):
        if np.ma.is_masked(value):
            raise ValueError(value)
        value = np.asarray(value.data)
    try:
        return _plain(value, depth)
    except ValueError:
        raise
    except Exception:  # a hostile __float__, __int__, __index__ or __iter__: a value TOML has no kind for
        raise ValueError(value) from None


def _plain(value, depth: int):
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "biufU":
        value = value.item()
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, str):  # np.str_ too; a subclass's own __str__ may say anything
        return str.__str__(value)
    if isinstance(value, (np.datetime64, np.timedelta64)):  # numpy counts a timedelta as an integer
        raise ValueError(value)
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real):
        try:
            return float(value)
        except (OverflowError, TypeError, ValueError):
            raise ValueError(value) from None
    if depth < 32 and isinstance(value, (list, tuple)):
        return [_toml(x, depth + 1) for x in value]
    if depth < 32 and isinstance(value, np.ndarray) and value.dtype.kind in "biufU" and value.ndim >= 1:
        return [_toml(x, depth + 1) for x in value]
    raise ValueError(value)


class _Names(Spec):
    """Variable names: any iterable of strings but a string (a list, a
    tuple, a generator, a numpy array of names)."""

    what = "a list of variable names"

    def accepts(self, value) -> bool:
        try:
            if iter(value) is value:  # an iterator (a generator): a look would use it up; simulate reads it once
                return True
        except TypeError:
            return False
        return _names(value) is not None


def _names(value) -> list[str] | None:
    if isinstance(value, (str, bytes, bytearray, dict)) or (isinstance(value, np.ndarray) and value.ndim != 1):
        return None
    try:
        items = iter(value)
    except TypeError:
        return None
    names = []
    endless = items is value  # an iterator may never end; a list, tuple or array has its length
    for n in items:  # read one at a time: an endless iterator is refused, not listed until memory ends
        if not isinstance(n, str):
            return None
        if endless and len(names) >= MAX_OUTPUT_NAMES:
            raise UsageError(f"simulate(): output = {show(value)}: more than {MAX_OUTPUT_NAMES:,} names: expected "
                             "a list of variable names (an endless iterator?)")
        names.append(str.__str__(n))  # its characters: a str subclass's __str__, __eq__, __hash__ are not asked
    return names


class _Signals(Spec):
    what = ("fmpy's structured array (a field time first, then a field per input) or the path of a CSV "
            "input file")

    def accepts(self, value) -> bool:
        return _is_structured(value) or PathSpec().accepts(value)


class _Number(Real):
    """Real's numbers, and a 0-d numpy array of one (np.array(2.0), as fmpy
    takes and start_values already did)."""

    def accepts(self, value) -> bool:
        if isinstance(value, np.ndarray) and not isinstance(value, np.ma.MaskedArray) and value.ndim == 0:
            return value.dtype.kind in "iuf" and super().accepts(value.item())
        return super().accepts(value)


_TIME = "a finite time in s"
_POSITIVE = "a number > 0 (s)"
_ARGUMENTS = dict(
    filename=PathSpec("the path of an .fmu, .ssp, .ssd, OspSystemStructure.xml or .toml file"),
    start_time=Optional(_Number(_TIME)), stop_time=Optional(_Number(_TIME)),
    step_size=Optional(_Number(_POSITIVE, positive=True)),
    relative_tolerance=Optional(_Number("a relative tolerance > 0", positive=True)),
    output_interval=Optional(_Number(_POSITIVE, positive=True)),
    start_values=Mapping(Text("a variable name"), _Value(), "a dict {variable name: value}"),
    input=Optional(_Signals()), output=Optional(_Names()),
    master=Optional(Either(Instance(MasterSettings, "a MasterSettings"),
                           Mapping(Text("a setting's name"), _Value(), "a dict of MasterSettings' fields"),
                           what="a MasterSettings or a dict of its fields")),
    progress=Flag(),
    output_format=Choice("structured", "pandas"),
)


@checked(**_ARGUMENTS)
def simulate(filename, start_time=None, stop_time=None, step_size=None, relative_tolerance=None,
             output_interval=None, start_values={}, input=None, output=None, *, master=None,  # noqa: B006 (fmpy's)
             progress: bool = False, output_format: str = "structured", **fmpy_only):
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
    `output` (the variables to record, any iterable of names; None: every
    output; empty: time alone). clockwork's own: `master` (MasterSettings,
    or a dict of its fields: those given apply, a MasterSettings' fields
    that differ from the defaults), `progress` (a progress bar) and
    `output_format` ("structured": fmpy's structured array, the default;
    "pandas": a pandas DataFrame with `time` a column, an FMI 3.0 array a
    column per element). fmpy's `fmi_type` may name the interface the FMU
    runs through ("ModelExchange" for an FMU without Co-Simulation); fmpy's
    other arguments are accepted at their defaults only.

    Numbers may be of any real type (int, float, numpy's, fractions); a
    value is checked against its FMU variable's type and range. Raises
    UsageError/SceneError for bad input, naming the argument, and
    SimulationError for a run that fails. An FMU that ends the simulation
    ends the result there.
    """
    fmi_type = fmpy_only.pop("fmi_type", None)
    if fmi_type is not None and not (type(fmi_type) is str and fmi_type in _FMI_TYPES):
        raise UsageError(f"simulate(fmi_type={show(fmi_type)}): expected 'CoSimulation', 'ModelExchange' or None")
    for name, value in fmpy_only.items():
        if name not in FMPY_ONLY:
            raise UsageError(f"simulate() got an unexpected argument {name}= (neither clockwork's nor fmpy's)")
        default = FMPY_ONLY[name]
        # compared without the value's own __eq__ (an array's gives an array, a hostile one anything)
        if value is default or (type(value) is type(default) and value == default) or (
                type(default) is bool and Flag().accepts(value) and bool(value) is default):
            continue
        why = _INSTEAD.get(name, "fmpy's option has no counterpart in clockwork")
        raise UsageError(f"simulate({name}={show(value)}): not supported ({why}); leave it out, or give "
                         f"fmpy's default {default!r}")
    output_format = str.__str__(output_format)  # checked: one of the choices
    if output_format == "pandas":
        from .results.load import pandas_module

        pandas_module("simulate(output_format='pandas')")  # missing: said before the run
    filename = fspath(filename)  # checked: a plain str now, __fspath__ asked once
    if isinstance(input, (str, os.PathLike)):
        input = fspath(input)
    # a str subclass key is its characters (its __str__, __eq__, __hash__ are not asked)
    start_values = {str.__str__(k): v for k, v in start_values.items()}
    if isinstance(master, dict):
        master = {str.__str__(k): v for k, v in master.items()}
    start_time, stop_time, step_size, relative_tolerance, output_interval = (
        None if x is None else float(x.item() if isinstance(x, np.ndarray) else x)  # a 0-d array: its number
        for x in (start_time, stop_time, step_size, relative_tolerance, output_interval))
    if output is not None:
        try:
            names = _names(output)  # read once: a generator is used up by it
        except UsageError:
            raise
        except Exception as e:  # a generator that raises
            raise UsageError(f"simulate(): output = {show(output)}: expected a list of variable names "
                             f"(reading it raised {type(e).__name__})") from None
        if names is None:
            raise UsageError(f"simulate(): output = {show(output)}: expected a list of variable names")
        output = names
    settings = _master_values(master)
    if step_size is not None and "step" in settings:
        raise UsageError("simulate(): step_size and master's step both given: expected one of them")

    # Values, not --set text: a start value's name is never read as a
    # section key (an FMU variable may be called experiment.stop).
    given = [Given("experiment", k, v, label) for k, v, label in
             (("start", start_time, "start_time"), ("stop", stop_time, "stop_time")) if v is not None]
    step_label = "step_size"
    if step_size is None and "step" not in settings and output_interval is not None:
        # fmpy's Co-Simulation steps at its output interval (and a refused step is named so)
        step_size, output_interval, step_label = output_interval, None, "output_interval"
    labels = {k: f"master[{show(k)}]" for k in settings}
    if step_size is not None:
        settings["step"], labels["step"] = step_size, step_label
    if relative_tolerance is not None:
        settings["tolerance"], labels["tolerance"] = relative_tolerance, "relative_tolerance"
    given += [Given("master", k, v, labels[k]) for k, v in settings.items()]
    if output_interval is not None:
        given.append(Given("record", "interval", output_interval, "output_interval"))
    given += [Given(None, k, _toml(v), f"start_values[{show(k)}]") for k, v in start_values.items()]
    path_input = input if isinstance(input, (str, os.PathLike)) else None
    scene = load_scene(filename, given, path_input)
    only = next(iter(scene.components)) if len(scene.components) == 1 else None
    if output is not None:  # one FMU: its variables by their own names, as fmpy names them
        own = variables_of(scene.components[only].model_description) if only is not None else {}
        names, items, seen = [], [], set()  # a set: a list's `in` made 100,000 names take minutes
        for i, o in enumerate(output):  # a name given twice is recorded once, as fmpy does
            ref = f"{only}.{o}" if o in own else o
            if ref not in seen:
                seen.add(ref)
                names.append(ref)
                items.append(f"output[{i}]")
        # an element of an array asked for whole too is in the whole (fmpy records y for y and y[0])
        keep = [k for k, ref in enumerate(names) if _array_of(scene, ref) not in seen]
        names, items = [names[k] for k in keep], [items[k] for k in keep]
        # the scene's plots are not drawn here, and may name columns left out
        given += [Given("record", "outputs", names, "output", tuple(items)), Given("plot", None, [], "output")]
        scene = load_scene(filename, given, path_input)
    if output_interval is not None:  # recorded every n-th step: fmpy's points only when n is whole
        n = output_interval / scene.master.step
        if not (round(n) >= 1 and abs(n - round(n)) <= 1e-9 * n):
            raise UsageError(f"simulate(): output_interval = {show(output_interval)}: expected a whole multiple of "
                             f"the step ({scene.master.step!r} s), or leave step_size out (fmpy's Co-Simulation "
                             "steps at its output interval)")
    if fmi_type is not None:
        _check_interface(scene, fmi_type)
    if scene.sweep is not None:
        raise UsageError(f"simulate({Path(filename).name}): the scene has a sweep of {len(scene.points())} points; "
                         "simulate() runs one (give a scene without [sweep], or run it with `clockwork run`)")
    if input is not None and path_input is None:
        scene = dataclasses.replace(scene, inputs=_array_inputs(input, scene))
    try:
        result = time_series(scene, {}, progress=progress, times=True)
    except ParametersRefused as e:  # the values given, not the run, are at fault
        raise SceneError(e.message, scene.path, f"start_values ({e.instance})") from None
    out = _structured(scene, result.get("series") or {"time": []}, only, None if output is None else names)
    if output_format == "pandas":
        from .results.load import as_pandas

        return as_pandas(out, "simulate(output_format='pandas')")
    return out


def _check_interface(scene, fmi_type: str) -> None:
    """fmpy's fmi_type names the interface the FMU runs through (Model
    Exchange for an FMU that has no Co-Simulation; in a system, every
    component's): UsageError for another."""
    what = f"simulate(fmi_type={fmi_type!r})"
    requested = _FMI_TYPES[fmi_type]
    shown = {"co-simulation": "Co-Simulation", "model-exchange": "Model Exchange"}
    for name, component in scene.components.items():
        md = component.model_description
        used = interface_of(md, component.interface)
        if used == requested:
            continue
        if scene.path.suffix.lower() != ".fmu":
            raise UsageError(f"{what}: the component {name} runs through its {shown[used]} interface (a scene "
                             "chooses with `interface`); leave fmi_type out")
        try:
            interface_of(md, requested)
        except SceneError as e:
            raise UsageError(f"{what}: {e.detail}") from None
        raise UsageError(f"{what}: {md.modelName} has both interfaces and an FMU file alone runs through its "
                         f'{shown[used]} interface; leave fmi_type out, or give a scene with interface = "{requested}"')


def _master_values(master) -> dict:
    if master is None:
        return {}
    if isinstance(master, MasterSettings):
        # its fields may have been changed after it checked them: each value is checked as a dict's
        default, out = MasterSettings(), {}
        for f in dataclasses.fields(master):
            value = getattr(master, f.name)
            if value is None or (type(value) is type(getattr(default, f.name)) and value == getattr(default, f.name)):
                continue
            try:
                out[f.name] = _toml(value)
            except ValueError:
                raise UsageError(f"simulate(): master.{f.name} = {show(value)}: expected {_Value.what}") from None
        return out
    return {k: _toml(v) for k, v in master.items()}


def _is_structured(x) -> bool:
    return isinstance(x, np.ndarray) and x.dtype.names is not None and x.ndim == 1


def _array_inputs(signals: np.ndarray, scene) -> Inputs:
    """fmpy's input array as the scene's input samples, checked as an input file is."""
    if isinstance(signals, np.ma.MaskedArray):
        # a masked entry has no value: its placeholder is not one (a structured mask: field by field)
        rows = sorted({int(i) for f in signals.dtype.names for i in np.flatnonzero(np.ma.getmaskarray(signals[f]))})
        if rows:
            raise UsageError(f"simulate(input=...): row {rows[0]} is masked: expected a value in every field "
                             "(fill it, or leave the row out)")
        signals = np.asarray(signals.data)
    names = list(signals.dtype.names)
    if names[0] != "time":
        raise UsageError(f"simulate(input=...): the first field is {names[0]!r}: expected time (fmpy's layout)")

    def fail(_line, column, detail):
        field = f" field {names[column]!r}" if column is not None else ""
        return UsageError(f"simulate(input=...):{field}: {detail}")

    # Each field's kind first: numpy would turn text, dates and objects into
    # floats (or fail) its own way. A field of arrays (fmpy's layout for an
    # FMI 3.0 array input, u of shape (2,)) is a column per element, u[0]
    # and u[1], row-major; the element names say whether the input has it.
    columns = []
    for j, n in enumerate(names):
        dt = signals.dtype[n]
        kinds = "iuf" if j == 0 else "biuf"
        if (dt.shape and (j == 0 or 0 in dt.shape)) or dt.base.kind not in kinds:
            what = "times in s (a field of floats or integers)" if j == 0 else \
                "a value per row (a field of floats, integers or bools, or an array of them)"
            got = f"a field of shape {dt.shape}" if dt.shape and dt.base.kind in kinds else f"dtype {dt.str}"
            raise fail(None, j, f"expected {what}, got {got}")
        if dt.shape:
            shape = _shape_of(scene, n)
            if shape != dt.shape:
                has = "names no variable" if shape is None else \
                    f"is of shape {shape}" if shape else "is a scalar"
                raise fail(None, j, f"a field of shape {dt.shape}: expected a field of the shape of the array input "
                                    f"it names ({n} {has})")
            columns += [(element_name(n, idx), signals[n][(slice(None), *idx)]) for idx in np.ndindex(*dt.shape)]
        else:
            columns.append((n, signals[n]))
    names = [n for n, _ in columns]
    if len(signals) == 0:
        raise UsageError("simulate(input=...): no rows: expected at least one sample (a row per time)")
    times = [float(t) for t in signals["time"]]
    for k, t in enumerate(times):
        if not math.isfinite(t):
            raise fail(None, 0, f"row {k}: expected a finite time in s, got {t!r}")
        if k and t < times[k - 1]:
            raise fail(None, 0, f"row {k}: {t!r} s is before the row above ({times[k - 1]!r} s): expected times "
                                "that never decrease (a time given twice is a step)")
    connected = {(c.dst_instance, c.dst_var) for c in scene.connections}
    given = {(n, p) for n, c in scene.components.items() for p in c.parameters}
    bound = targets(names, scene.components, connected, given, fail)
    cols = []
    for j, (inst, var, v) in enumerate(bound, start=1):
        column = []
        for k, x in enumerate(columns[j][1].tolist()):  # Python's numbers (numpy's repr is not theirs)
            try:
                column.append(sample_value(x, v))
            except ValueError as e:
                raise fail(None, j, f"row {k}: {e}, got {x!r}") from None
        cols.append(column)
    samples = make_samples(times, cols, bound)
    digest = hashlib.sha256(signals.tobytes() + repr(signals.dtype).encode()).hexdigest()
    return Inputs(None, digest, samples)


def _array_of(scene, ref: str) -> str | None:
    """"instance.array" when `ref` ("instance.variable") names an element of an FMI 3.0 array, else None."""
    inst, dot, var = ref.partition(".")
    while dot and inst not in scene.components:  # instance names may hold dots
        head, dot, var = var.partition(".")
        inst = f"{inst}.{head}"
    component = scene.components.get(inst)
    if component is None:
        return None
    v = variables_of(component.model_description).get(var)
    array = getattr(v, "array", None)
    return None if array is None else f"{inst}.{array.name}"


def _shape_of(scene, name: str) -> tuple | None:
    """The shape of the variable an input field names (() for a scalar), or None."""
    variables = {n: variables_of(c.model_description) for n, c in scene.components.items()}
    split = split_ref(name, variables)
    if (split is None or split[1] not in variables[split[0]]) and len(variables) == 1:
        split = (next(iter(variables)), name)
    v = variables[split[0]].get(split[1]) if split is not None else None
    return None if v is None else tuple(getattr(v, "shape", None) or ())


def _empty_arrays(scene, recorded: list[str] | None) -> list:
    """The FMI 3.0 arrays of size 0 among the variables asked for
    (`recorded`: "instance.variable"; None: the outputs of an FMU or SSP
    alone): (instance, variable)."""
    if recorded is None and scene.path.suffix.lower() == ".toml":
        return []  # a scene's [record] says what it records
    asked = None if recorded is None else set(recorded)
    return [(n, v) for n, c in scene.components.items() for v in c.model_description.modelVariables
            if getattr(v, "shape", None) and math.prod(v.shape) == 0
            and (f"{n}.{v.name}" in asked if asked is not None else v.causality == "output")]


def _structured(scene, series: dict, only: str | None, recorded: list[str] | None = None) -> np.ndarray:
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
    for inst, v in _empty_arrays(scene, recorded):  # no element to record: a field of their shape, as fmpy's
        dtype = _DTYPES.get(v.type, np.float64)
        fields.append((v.name if only is not None else f"{inst}.{v.name}", dtype, tuple(v.shape)))
        data.append(np.empty((len(data[0]), *v.shape), dtype=dtype))
    out = np.empty(len(data[0]), dtype=fields)
    for field, column in zip(fields, data):
        out[field[0]] = column
    return out
