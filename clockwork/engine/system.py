"""A wired, instantiated system of FMUs: the engine's front door.

Scenes are turned into one by the analyses (clockwork.analyses.context);
tests, benchmarks and the Python API build one directly:
``System({"pendulum": ("Pendulum", {...})}, ["pendulum.phi -> escapement.phi", ...],
MasterSettings(...))``. A model name is looked up in $CLOCKWORK_FMU_DIR
(else the repository's fmus/); a path ending .fmu is taken as it is.
"""

from __future__ import annotations

import difflib
from pathlib import Path

from ..errors import ClosedError, SceneError, UsageError
from .description import resolve_fmu
from .fmu import Instance, free_all
from .fmu3 import make_instance
from .compiled import make_master
from .settings import MasterSettings
from .wiring import Link, parse_link


class System:
    def __init__(self, components: dict[str, tuple[str, dict]], connections: list[str],
                 settings: MasterSettings | None = None, record: dict[str, list[str]] | None = None,
                 start_time: float = 0.0, model_descriptions: dict | None = None):
        if not isinstance(components, dict) or not all(
                isinstance(c, (tuple, list)) and len(c) == 2 and isinstance(c[1], dict) for c in components.values()):
            raise UsageError("System: components must be {instance: (model name or .fmu path, {parameter: value})}")
        self.parameters = {name: dict(params) for name, (_, params) in components.items()}
        self.instances: dict[str, Instance] = {}
        self._freed = False
        # On a clean exit of a `with` block, hand the system to this callable
        # instead of freeing it (analyses.context.reusing_systems).
        self.release = None
        settings = settings or MasterSettings()
        try:
            for name, (fmu, _) in components.items():
                md = (model_descriptions or {}).get(name)
                inst = make_instance(name, resolve_fmu(str(fmu), Path.cwd(), settings.fmi_version), md,
                                     settings.early_return,
                                     bool(settings.extrapolation) or settings.iterations > 0)
                inst.instantiate()
                self.instances[name] = inst
            known = {n: inst.variables for n, inst in self.instances.items()}
            links = [c if isinstance(c, Link) else self._parse_link(c, known) if isinstance(c, str) else Link(*c)
                     for c in connections]
            for link in links:
                self._variable(link.src, link.output, "output", "a link's source")
                self._variable(link.dst, link.input, "input", "a link's target")
            for what, table in (("a parameter", self.parameters), ("a recorded output", record or {})):
                for inst, names in table.items():
                    for var in names:
                        self._variable(inst, var, None, what)
            self.master = make_master(self.instances, links, settings,
                                 start_time=start_time, extra_outputs=record)
            self.master.initialize(self.parameters)
        except BaseException:
            self.free()
            raise

    master = None  # until built

    def restart(self, parameters: dict[str, dict[str, object]]) -> None:
        """Start again from `parameters` on the same instances and wiring:
        fmi2Reset every FMU, initialize again, statistics from zero. The
        same bits as a new System with these parameters, without loading and
        instantiating the FMUs again."""
        if self._freed:
            raise ClosedError("this System was freed (used after its `with` block or free()): build a new System")
        for inst, names in parameters.items():
            for var in names:
                self._variable(inst, var, None, "a parameter")
        self.parameters = {name: dict(p) for name, p in parameters.items()}
        self.master.restart(self.parameters)

    @staticmethod
    def _parse_link(text: str, known: dict) -> Link:
        """The link, its instance names matched longest first; where nothing
        matches, split at the first dot so that _variable names what is missing."""
        try:
            return parse_link(text, known)
        except SceneError:
            return parse_link(text)

    def _variable(self, instance: str, name: str, causality: str | None, what: str):
        """The variable `instance.name`, or UsageError naming both (with the nearest names)."""
        if self._freed:
            raise ClosedError("this System was freed (used after its `with` block or free()): build a new System")
        inst = self.instances.get(instance)
        if inst is None:
            close = difflib.get_close_matches(str(instance), list(self.instances), n=1)
            raise UsageError(f"{what} {instance}.{name}: no instance {instance!r}"
                             + (f" (did you mean {close[0]}?)" if close else "")
                             + f"; the instances are {', '.join(self.instances) or 'none'}")
        v = inst.variables.get(name)
        if v is None:
            close = difflib.get_close_matches(str(name), list(inst.variables), n=1)
            raise UsageError(f"{what} {instance}.{name}: {inst.model_name} has no variable {name!r}"
                             + (f" (did you mean {close[0]}?)" if close else ""))
        if causality is not None and v.causality != causality:
            raise UsageError(f"{what} {instance}.{name}: expected an {causality}, {name} is a {v.causality}")
        return v

    def value(self, instance: str, name: str) -> float:
        """Current value of a Real variable (not on the hot path)."""
        self._variable(instance, name, None, "value")
        return self.instances[instance].get_real([name])[0]

    def output(self, instance: str, name: str) -> float:
        """Cached value of a connected or recorded output at the current point."""
        self._variable(instance, name, None, "output")
        port = self.master.ports[instance]
        if name not in port.out_names:
            raise UsageError(f"output {instance}.{name}: neither connected nor recorded; "
                             f"record it (record={{{instance!r}: [{name!r}]}}) or use value()")
        return port.out[port.out_names.index(name)]

    def free(self) -> None:
        free_all(self.instances)
        self.instances = {}
        self._freed = True
        if self.master is not None:
            self.master.stop_threads()  # now, not when the collector finds the master
            _close(self.master)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        release, self.release = self.release, None
        if release is not None and exc_type is None and self.instances:
            release(self)
        else:
            self.free()


def _close(master) -> None:
    """Every public method of a freed system's master raises ClosedError
    (the FMU instances it would call are gone), also through a reference
    kept from before."""
    def closed(*args, **kwargs):
        raise ClosedError("this System was freed (used after its `with` block or free()): build a new System")
    for name in dir(type(master)):
        if not name.startswith("_") and callable(getattr(type(master), name, None)):
            setattr(master, name, closed)
