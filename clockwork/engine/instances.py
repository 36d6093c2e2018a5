"""The one factory: an instance of any FMU the engine runs.

Every command, the scene loader, ``System`` and the API make their
instances here. It is the one place that reads the FMU's version and
interface to choose a face (FMI 1.0, 2.0 or 3.0 Co-Simulation; FMI 2.0 or
3.0 Model Exchange: the engine's wrapper composing the integrator with the
FMU's Model Exchange face); what it returns implements the instance
contract (fmi/contract.py) whichever it is, so the master never asks.
"""

from __future__ import annotations

from ..errors import SceneError
from ..fmi.contract import Instance
from ..fmi.description import fmi_version, read_fmu
from ..fmi.cs1 import Instance1
from ..fmi.clocks import is_scheduled
from ..fmi.cs2 import Instance2
from ..fmi.cs3 import Instance3
from ..fmi.me2 import ModelExchange2
from ..fmi.me3 import ModelExchange3
from ..fmi.scheduled import ScheduledInstance
from .model_exchange import MEInstance, MEOptions, interface_of, model_exchange_problem

_MODEL_EXCHANGE_FACES = {2: ModelExchange2, 3: ModelExchange3}


def make_instance(name, path, model_description=None, early_return: bool = True, intermediate_update: bool = False,
                  interface: str | None = None, options: MEOptions | None = None) -> Instance:
    """An instance of the FMU at `path` through the interface asked for
    (``interface_of``: `interface`, else Co-Simulation where the FMU has it):
    a Model Exchange wrapper with `options`, else its Co-Simulation face
    (early return allowed where the FMU declares it, unless `early_return`
    is false; intermediate update where it provides it and
    `intermediate_update` asks for it)."""
    md = model_description or read_fmu(path, need_binary=False)[0]
    version = fmi_version(md)
    if interface_of(md, interface) == "model-exchange":
        problem = model_exchange_problem(md)
        if problem:
            raise SceneError(f"{path}: {problem}")
        return MEInstance(name, path, md, _MODEL_EXCHANGE_FACES[version](), options)
    if version == 3 and is_scheduled(md):
        return ScheduledInstance(name, path, md)
    if version == 3:
        return Instance3(name, path, md, early_return, intermediate_update)
    if version == 1:
        return Instance1(name, path, md)
    return Instance2(name, path, md)
