"""A scene at one sweep point, as an analysis sees it.

``parameters(scene, point)`` gives every component's effective parameters
(``Parameters``: the scene's value, else the FMU's start value, in the
variable's own SI unit). ``build_system`` wires and instantiates the FMUs
with them; ``master_settings`` and ``experiment`` apply a point's master
and experiment values. Inside ``reusing_systems()`` (a sweep's points in
one process), ``build_system`` hands a finished point's instances to the
next point of the same structure: fmi2Reset and new parameters instead of
loading and instantiating every FMU again.
"""

from __future__ import annotations

import dataclasses
from contextlib import contextmanager
from contextvars import ContextVar

from ..fmi.description import var_unit, variables
from ..engine.settings import MasterSettings
from ..engine.system import System
from ..scene.model import rates as component_rates
from ..errors import SimulationError
from .escapements import MODELS as ESCAPEMENTS  # the registered escapements' models (re-exported)


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
    """The scene's master settings with a point's master values: a copy,
    which the run may change without changing the scene."""
    changes = {key: value for (group, key), value in (point or {}).items() if group == "master"}
    return dataclasses.replace(scene.master, **changes)


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


class _IdleSystem:
    """The one system kept between points, with what it was built from."""

    def __init__(self):
        self.key: tuple | None = None
        self.system: System | None = None

    def take(self, key: tuple) -> System | None:
        if self.system is None or self.key != key:
            return None
        system, self.system, self.key = self.system, None, None
        return system

    def keep(self, key: tuple, system: System) -> None:
        self.close()  # one idle system: a sweep over structure does not pile them up
        self.key, self.system = key, system

    def close(self) -> None:
        if self.system is not None:
            self.system.free()
        self.key = self.system = None


_idle: ContextVar[_IdleSystem | None] = ContextVar("clockwork_idle_system", default=None)


@contextmanager
def reusing_systems():
    """Within this block, build_system reuses the instances of the last
    point that finished cleanly when the next point has the same FMUs,
    connections, master settings, start time and recorded outputs."""
    idle = _IdleSystem()
    token = _idle.set(idle)
    try:
        yield
    finally:
        _idle.reset(token)
        idle.close()


_series_sink: ContextVar = ContextVar("clockwork_series_sink", default=None)


@contextmanager
def streaming_series(make_sink):
    """Within this block a time series is written as the run goes:
    ``make_sink(names, text_names)`` gives the Recorder's sink
    (results.series.SeriesWriter; made by the run layer, which knows the
    output directory) and the result's "series" is what its ``close``
    gives. Outside, the series is kept in memory (clockwork.simulate, a
    sweep's points)."""
    token = _series_sink.set(make_sink)
    try:
        yield
    finally:
        _series_sink.reset(token)


def series_sink():
    """The ``make_sink`` of the enclosing ``streaming_series``, or None."""
    return _series_sink.get()


def build_system(scene, point: dict | None = None, record: dict[str, list[str]] | None = None) -> System:
    params = parameters(scene, point)
    start, _ = experiment(scene, point)
    settings = master_settings(scene, point)
    rates = component_rates(settings, scene.components)
    idle = _idle.get()
    system = None
    if idle is not None:
        key = (tuple((n, str(c.fmu_path), c.sha256, c.interface, c.step) for n, c in scene.components.items()),
               tuple(scene.connections), repr(settings), start,
               tuple(sorted((k, tuple(v)) for k, v in (record or {}).items())),
               id(scene.inputs.samples) if scene.inputs is not None else None)
        system = idle.take(key)
        if system is not None:
            try:
                system.restart(params)
            except BaseException:
                system.free()
                raise
    if system is None:
        components = {n: (str(c.fmu_path), params[n]) for n, c in scene.components.items()}
        mds = {n: c.model_description for n, c in scene.components.items()}
        system = System(components, [tuple(c) for c in scene.connections], settings,
                        record=record, start_time=start, model_descriptions=mds,
                        interfaces={n: c.interface for n, c in scene.components.items()},
                        inputs=scene.inputs.samples if scene.inputs is not None else None,
                        labels={n: c.fmu_label for n, c in scene.components.items() if c.fmu_label},
                        **({"rates": rates} if rates else {}))
    if idle is not None:
        system.release = lambda s: idle.keep(key, s)
    return system
