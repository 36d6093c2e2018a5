"""A scene at one sweep point, as an analysis sees it.

``parameters(scene, point)`` gives every component's effective parameters
(``Parameters``: the scene's value, else the FMU's start value, in the
variable's own SI unit). ``build_system`` wires and instantiates the FMUs
with them; ``master_settings`` and ``experiment`` apply a point's master
and experiment values.
"""

from __future__ import annotations

from ..engine.description import var_unit, variables
from ..engine.settings import MasterSettings
from ..engine.system import System
from ..errors import SimulationError

ESCAPEMENTS = ("GrasshopperEscapement", "ChronometerEscapement")


class Parameters(dict):
    """One component's effective parameters, by variable name.

    As a dict it holds what the scene (and the sweep point) sets: iterating
    gives exactly the values the FMU is told. Looking up a parameter that
    the scene leaves out gives the FMU's start value; ``unit(name)`` gives
    the unit every value is in (the variable's own, SI).
    """

    def __init__(self, values: dict, model_description, instance: str):
        super().__init__(values)
        self._variables = variables(model_description)
        self._model = model_description.modelName
        self._instance = instance

    def _start(self, name: str):
        v = self._variables.get(name)
        if v is None or v.causality not in ("parameter", "input") or v.start is None:
            raise SimulationError(f"{self._instance} ({self._model}) has no parameter {name} with a start value")
        if v.type == "Real":
            return float(v.start)
        if v.type in ("Integer", "Enumeration"):
            return int(v.start)
        if v.type == "Boolean":
            return str(v.start).strip().lower() in ("true", "1")
        return v.start

    def __missing__(self, name: str):
        return self._start(name)

    def get(self, name: str, default=None):
        if name in self:
            return self[name]
        v = self._variables.get(name)
        if v is None or v.start is None or v.causality not in ("parameter", "input"):
            return default
        return self._start(name)

    def unit(self, name: str) -> str | None:
        v = self._variables.get(name)
        if v is None:
            raise SimulationError(f"{self._instance} ({self._model}) has no variable {name}")
        return var_unit(v)


def find_component(scene, model: str | tuple[str, ...]) -> str | None:
    """Name of the first component whose model is `model` (or one of them)."""
    models = (model,) if isinstance(model, str) else model
    for name, c in scene.components.items():
        if c.model_description.modelName in models:
            return name
    return None


def master_settings(scene, point: dict | None = None) -> MasterSettings:
    values = scene.master.as_dict()
    for (group, key), value in (point or {}).items():
        if group == "master":
            values[key] = value
    return MasterSettings(**values)


def experiment(scene, point: dict | None = None) -> tuple[float, float]:
    """(start, stop), s."""
    start, stop = scene.experiment.start, scene.experiment.stop
    for (group, key), value in (point or {}).items():
        if group == "experiment":
            start, stop = (value, stop) if key == "start" else (start, value)
    return start, stop


def parameters(scene, point: dict | None = None) -> dict[str, Parameters]:
    """{instance: Parameters} with the point's values applied."""
    params = scene.parameters()
    for (inst, var), value in (point or {}).items():
        if inst in params:
            params[inst][var] = value
    return {n: Parameters(values, scene.components[n].model_description, n) for n, values in params.items()}


def build_system(scene, point: dict | None = None, record: dict[str, list[str]] | None = None) -> System:
    params = parameters(scene, point)
    start, _ = experiment(scene, point)
    components = {n: (str(c.fmu_path), params[n]) for n, c in scene.components.items()}
    mds = {n: c.model_description for n, c in scene.components.items()}
    return System(components, [tuple(c) for c in scene.connections], master_settings(scene, point),
                  record=record, start_time=start, model_descriptions=mds)
