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

Every output is recorded (where there is none, as fmpy: up to five
continuous states, else up to five local variables), the analysis is a
time series, and the default plot draws what is recorded.
"""

from __future__ import annotations

from pathlib import Path

from ..engine.description import FmuError, TEXT_TYPES, read_fmu
from ..errors import SceneError
from ..files import absent
from ..numbers import parse_real
from .checks import instance_problem
from .model import Component
from .ssp.read import SspScene

_MAX_FALLBACK = 5  # fmpy records at most this many states or locals when an FMU has no outputs


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
        try:
            return parse_real(str(text).strip())
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
            while span > 0 and step > 0 and span / step > 1000:
                step *= 2
        else:
            step = float(auto_interval(span)) if span > 0 else 1e-3  # fmpy.util.auto_interval
    return {"start": start, "stop": stop}, step


def default_record(md, instance: str) -> list[str]:
    """What fmpy records by default: every output; where there is none, up to
    five continuous states, else up to five local variables."""
    def usable(v) -> bool:  # an FMI 3.0 array is recorded element by element, as fmpy does
        return v is not None and v.type not in ("Clock",)

    outputs = [v for v in md.modelVariables if v.causality == "output" and usable(v)]
    if not outputs:
        states = [getattr(d.variable, "derivative", None) for d in (md.derivatives or [])]
        outputs = [v for v in states if usable(v) and v.type not in TEXT_TYPES][:_MAX_FALLBACK]
    if not outputs:
        outputs = [v for v in md.modelVariables
                   if v.causality == "local" and usable(v) and v.type not in TEXT_TYPES][:_MAX_FALLBACK]
    return [f"{instance}.{v.name}" for v in outputs]


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
    sections = {"experiment": experiment, "master": {"step": step},
                "record": {"outputs": default_record(md, name)}}
    component = Component(name, path.resolve(), digest, md, {}, indicators)
    return SspScene(md.modelName, md.description or "", {name: component}, (), sections, digest)
