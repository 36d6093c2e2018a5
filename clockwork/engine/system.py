"""A wired, instantiated system of FMUs: the engine's front door.

Scenes are turned into one by the analyses (clockwork.analyses.context);
tests, benchmarks and the Python API build one directly:
``System({"pendulum": ("Pendulum", {...})}, ["pendulum.phi -> escapement.phi", ...],
MasterSettings(...))``. A model name is looked up in $CLOCKWORK_FMU_DIR
(else the repository's fmus/); a path ending .fmu is taken as it is.
"""

from __future__ import annotations

from pathlib import Path

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
        self.parameters = {name: dict(params) for name, (_, params) in components.items()}
        self.instances: dict[str, Instance] = {}
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
            links = [parse_link(c) if isinstance(c, str) else Link(*c) for c in connections]
            self.master = make_master(self.instances, links, settings,
                                 start_time=start_time, extra_outputs=record)
            self.master.initialize(self.parameters)
        except BaseException:
            self.free()
            raise

    def restart(self, parameters: dict[str, dict[str, object]]) -> None:
        """Start again from `parameters` on the same instances and wiring:
        fmi2Reset every FMU, initialize again, statistics from zero. The
        same bits as a new System with these parameters, without loading and
        instantiating the FMUs again."""
        self.parameters = {name: dict(p) for name, p in parameters.items()}
        self.master.restart(self.parameters)

    def value(self, instance: str, name: str) -> float:
        """Current value of a Real variable (not on the hot path)."""
        return self.instances[instance].get_real([name])[0]

    def output(self, instance: str, name: str) -> float:
        """Cached value of a connected or recorded output at the current point."""
        port = self.master.ports[instance]
        return port.out[port.out_names.index(name)]

    def free(self) -> None:
        free_all(self.instances)
        self.instances = {}

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        release, self.release = self.release, None
        if release is not None and exc_type is None and self.instances:
            release(self)
        else:
            self.free()
