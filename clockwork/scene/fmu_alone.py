"""One FMU as a scene: `clockwork run X.fmu` (docs/own-fmu.md).

The third reader beside the TOML loader and the SSP reader: it gives the
components and the sections a scene file would hold, and load.py checks
them as it checks an SSP's. The FMU is the one component, named after its
model (``modelName``, else its ``modelIdentifier`` where the model name is
not a usable instance name). Its DefaultExperiment gives the experiment and
the step, with fmpy's defaults (``fmpy.simulate_fmu``, fmpy 0.3.32) where
an attribute is absent:

- start: ``startTime``, else 0 s;
- stop: ``stopTime``, else start + 1 s;
- step: ``stepSize``; else, as fmpy, the FMI 3.0 ``fixedInternalStepSize``
  of its Co-Simulation interface, doubled until the run has at most 1000
  steps, else fmpy's ``auto_interval`` of the experiment's length (500 to
  1000 steps). fmpy widens a declared ``stepSize`` too, to at most 1000
  steps; clockwork keeps the step the FMU declares;
- tolerance: ``tolerance``, passed to the FMU (the engine reads it: the
  scene leaves ``master.tolerance`` unset).

Every output is recorded (where there is none, as fmpy: the first five
continuous states, else the first five variables: ``default_record``), the
analysis is a time series, and the default plot draws what is recorded.
"""

from __future__ import annotations

import math
from pathlib import Path

from ..fmi.description import FmuError, read_fmu
from ..errors import SceneError
from ..files import absent
from ..numbers import XSD_SPECIAL, parse_real
from .checks import instance_problem
from .model import Component
from .ssp.read import SspScene

_MAX_FALLBACK = 5  # fmpy records at most this many states or variables when an FMU has no outputs


def instance_name(md) -> str:
    """The one instance's name: the model's name, where it is a usable instance name."""
    ident = md.coSimulation.modelIdentifier if md.coSimulation is not None else None
    for name in (md.modelName, ident, "model"):
        if isinstance(name, str) and instance_problem(name) is None:
            return name
    return "model"


def experiment_times(md, path: Path) -> tuple[dict, float]:
    """({"start", "stop"} in s, the step in s) from the DefaultExperiment, with fmpy's defaults."""
    from fmpy.util import auto_interval

    de = md.defaultExperiment

    def attribute(name: str) -> float | None:
        text = getattr(de, name, None) if de is not None else None
        if text in (None, ""):
            return None
        try:  # xs:double: INF and NaN are refused by the scene's checks, named by this attribute
            return parse_real(str(text).strip(), XSD_SPECIAL)
        except ValueError:
            raise SceneError(f"expected a decimal number, got {str(text)[:40]!r}", path,
                             f"modelDescription.xml: DefaultExperiment {name}") from None

    start = attribute("startTime")
    start = 0.0 if start is None else start
    stop = attribute("stopTime")
    stop = start + 1.0 if stop is None else stop
    step = attribute("stepSize")
    span = stop - start
    if step is None:
        cs = md.coSimulation
        fixed = getattr(cs, "fixedInternalStepSize", None) if cs is not None else None
        if fixed not in (None, ""):
            try:
                step = parse_real(str(fixed).strip())
            except ValueError:
                raise SceneError(f"expected a decimal number, got {str(fixed)[:40]!r}", path,
                                 "modelDescription.xml: CoSimulation fixedInternalStepSize") from None
            # fmpy doubles it to at most 1000 steps (a span that is not positive is refused later)
            while 0 < span < math.inf and step > 0 and span / step > 1000:
                step *= 2
        else:  # fmpy.util.auto_interval (a span that is not positive or finite is refused later)
            step = float(auto_interval(span)) if 0 < span < math.inf else 1e-3
    return {"start": start, "stop": stop}, step


def experiment_labels(md, path: Path) -> dict[str, tuple[str, str]]:
    """Where each value of ``experiment_times`` came from, for the errors
    that refuse it later (load.py): the DefaultExperiment attribute, or what
    stands in for an absent one."""
    de = md.defaultExperiment

    def given(name: str) -> bool:
        return de is not None and getattr(de, name, None) not in (None, "")

    where = "modelDescription.xml: DefaultExperiment"
    labels = {}
    if given("startTime"):
        labels["experiment.start"] = (str(path), f"{where} startTime")
    if given("stopTime"):
        labels["experiment.stop"] = (str(path), f"{where} stopTime")
    elif given("startTime"):
        labels["experiment.stop"] = (str(path), f"{where} startTime (no stopTime: the run stops 1 s after it)")
    if given("stepSize"):
        labels["master.step"] = (str(path), f"{where} stepSize")
    elif md.coSimulation is not None and getattr(md.coSimulation, "fixedInternalStepSize", None) not in (None, ""):
        labels["master.step"] = (str(path), "modelDescription.xml: CoSimulation fixedInternalStepSize (doubled to "
                                            "at most 1000 steps)")
    else:
        labels["master.step"] = (str(path), f"{where} (no stepSize: fmpy's auto_interval of the span)")
    return labels


# What fmpy's Recorder keeps of the variables it is given (fmpy 0.3.32,
# simulation.Recorder): numbers and Booleans; Strings, Binaries and Clocks
# are dropped, and a variable named "time" (the time column's name).
_FMPY_UNRECORDED = ("String", "Binary", "Clock")
# The order of the Recorder's columns: by type (FMI 3.0's Float64 and Int32
# under FMI 2.0's names here: Real, Integer), Enumerations with the integers
# (Integer in FMI 1.0/2.0, Int64 in 3.0); text last (fmpy has none).
_FMPY_TYPE_ORDER = {t: i for i, t in enumerate(
    ("Float32", "Real", "Int8", "UInt8", "Int16", "UInt16", "Integer", "UInt32", "Int64", "UInt64", "Boolean"))}


def default_record(md, instance: str) -> list[str]:
    """What fmpy's simulate_fmu records by default (fmpy.simulation.
    _get_output_variables): every output; where there is none, the first
    five continuous states; else the first five variables of the model,
    whatever their causality (fmpy's rule for "local variables" compares
    the variability with "local", which no variable has, so this is what it
    records). Of those, what fmpy's Recorder drops is dropped here too, and
    so is the independent variable (it is the time column) and an FMI 3.0
    structural parameter (a size: recorded only when asked for by name).
    An output of type String is recorded, where fmpy drops it: clockwork
    writes text columns (docs/fmpy-migration.md)."""
    def kept(v) -> bool:
        return (v is not None and v.name != "time" and v.type not in _FMPY_UNRECORDED
                and v.causality not in ("independent", "structuralParameter"))

    chosen = [v for v in md.modelVariables if v.causality == "output" and v.type != "Clock"
              and not getattr(v, "clocks", None)]  # clocked: recorded at their clocks' ticks (engine/clocks.py)
    if not chosen:
        states = [getattr(d.variable, "derivative", None) for d in (md.derivatives or [])][:_MAX_FALLBACK]
        chosen = [v for v in states if kept(v)]
        if not states:
            chosen = [v for v in md.modelVariables[:_MAX_FALLBACK] if kept(v)]
    # fmpy's columns come by type, in the order of the model's variables within a type
    enum = "Int64" if md.fmiVersion.startswith("3") else "Integer"
    chosen.sort(key=lambda v: _FMPY_TYPE_ORDER.get(enum if v.type == "Enumeration" else v.type,
                                                   len(_FMPY_TYPE_ORDER)))
    return [f"{instance}.{v.name}" for v in chosen]


def read_fmu_scene(path: str | Path) -> SspScene:
    """An FMU alone, as a scene's components and sections; raises SceneError."""
    path = Path(path)
    if not path.exists():
        raise SceneError(absent(path, "an FMU file", "no such FMU file"), path)
    if path.is_dir():
        raise SceneError("is a directory, expected an FMU file (a zip archive)", path)
    try:
        md, digest, indicators = read_fmu(path)
    except FmuError as e:
        raise SceneError(str(e)) from None
    name = instance_name(md)
    experiment, step = experiment_times(md, path)
    master = {"step": step}
    cs = md.coSimulation
    if indicators and cs is not None and (md.fmiVersion == "1.0" or not cs.canGetAndSetFMUstate):
        # Locating its own events would roll it back, which it cannot: alone, it runs on the
        # grid as fmpy runs it (--set master.event_location=true is still refused, saying why).
        master["event_location"] = False
    sections = {"experiment": experiment, "master": master,
                "record": {"outputs": default_record(md, name)}}
    component = Component(name, path.resolve(), digest, md, {}, indicators)
    return SspScene(md.modelName, md.description or "", {name: component}, (), sections, digest,
                    labels=experiment_labels(md, path))
