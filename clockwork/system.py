"""A wired, instantiated system of FMUs, built without a scene file.

Scenes go through clockwork.scene first; tests, benchmarks and the Python
API use this directly: ``System({"pendulum": ("Pendulum", {...})},
["pendulum.phi -> escapement.phi", ...], MasterSettings(...))``.
"""

from __future__ import annotations

import os
from pathlib import Path

from .errors import SceneError
from .fmu import Instance
from .graph import Link
from .master import Master, MasterSettings

ROOT = Path(__file__).resolve().parents[1]


def fmu_path(name_or_path: str | os.PathLike) -> Path:
    """A model name resolved in $CLOCKWORK_FMU_DIR or the repository's fmus/."""
    p = Path(name_or_path)
    if p.suffix == ".fmu":
        return p
    base = Path(os.environ.get("CLOCKWORK_FMU_DIR", ROOT / "fmus"))
    path = base / f"{name_or_path}.fmu"
    if not path.exists():
        raise SceneError(f"FMU {name_or_path!r} not found at {path}; build the FMUs with "
                         f"`cmake -S . -B build -G Ninja && cmake --build build`")
    return path


def parse_link(text: str) -> Link:
    try:
        src, dst = (s.strip() for s in text.split("->"))
        a, b = src.split(".", 1)
        c, d = dst.split(".", 1)
    except ValueError:
        raise SceneError(f"connection {text!r}: expected 'instance.output -> instance.input'") from None
    return Link(a, b, c, d)


class System:
    def __init__(self, components: dict[str, tuple[str, dict]], connections: list[str],
                 settings: MasterSettings | None = None, record: dict[str, list[str]] | None = None,
                 start_time: float = 0.0, model_descriptions: dict | None = None):
        self.parameters = {name: dict(params) for name, (_, params) in components.items()}
        self.instances: dict[str, Instance] = {}
        try:
            for name, (fmu, _) in components.items():
                md = (model_descriptions or {}).get(name)
                inst = Instance(name, fmu_path(fmu), md)
                inst.instantiate()
                self.instances[name] = inst
            links = [parse_link(c) if isinstance(c, str) else Link(*c) for c in connections]
            self.master = Master(self.instances, links, settings or MasterSettings(),
                                 start_time=start_time, extra_outputs=record)
        except BaseException:
            self.free()
            raise
        self.master.initialize(self.parameters)

    def value(self, instance: str, name: str) -> float:
        """Current value of a Real variable (not on the hot path)."""
        return self.instances[instance].get_real([name])[0]

    def output(self, instance: str, name: str) -> float:
        """Cached value of a connected or recorded output at the current point."""
        port = self.master.ports[instance]
        return port.out[port.out_names.index(name)]

    def free(self) -> None:
        for inst in self.instances.values():
            try:
                inst.free()
            except Exception:
                pass
        self.instances = {}

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.free()
