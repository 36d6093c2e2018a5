"""The compiled stepping core on FMUs whose runtime no one here wrote.

Two container FMUs are built from installed packages around our FMUs:

- fmpy's container (fmpy.container_fmu): Pendulum and Drag in a closed
  loop, with its own Rust runtime (container_fmu.so);
- fmu-manipulation-toolbox's container (`fmucontainer`), from the
  description `clockwork export-ssp --container-dir` writes for
  core_grasshopper_drag: pendulum, escapement and drag.

Each runs as one component of a clockwork System on both engines, and
under fmpy's own ``simulate_fmu`` with the same communication step. The
engines agree bit for bit; fmpy calls the same fmi2 functions with the
same step, and agrees bit for bit too.
"""

from __future__ import annotations

import copy
import uuid
from pathlib import Path

import numpy as np
import pytest

from clockwork.engine import MasterSettings, System
from clockwork.engine.compiled import CompiledMaster
from clockwork.engine.master import Master
from clockwork.engine.recording import Recorder
from interop_common import FMU_DIR, fmutool_container


def _fmpy_container(out: Path) -> Path:
    """Pendulum + Drag (pendulum.w -> drag.w, drag.tau -> pendulum.tau_drag)
    in fmpy's container; outputs phi, w; parameter phi_start."""
    from fmpy import read_model_description
    from fmpy.container_fmu import Configuration
    from fmpy.container_fmu.cli import create_container_fmu
    from fmpy.container_fmu.config import Component, Connection
    from fmpy.model_description import CoSimulation, DefaultExperiment, ModelDescription, ModelVariable, Unknown

    def component(name, model):
        path = FMU_DIR / f"{model}.fmu"
        return Component(name=name, filename=path, modelDescription=read_model_description(path))

    def variable(c, name, float64=False):
        v = next(v for v in c.modelDescription.modelVariables if v.name == name)
        if float64:  # fmpy writes a connection's type by its FMI 2 name; the container reads FMI 3's
            v = copy.copy(v)
            v.type = "Float64"
        return v

    pend, drag = component("pendulum", "Pendulum"), component("drag", "Drag")
    md = ModelDescription(fmiVersion="2.0", modelName="PendulumDrag", instantiationToken=f"{{{uuid.uuid4()}}}",
                          coSimulation=CoSimulation(modelIdentifier="container_fmu"),
                          defaultExperiment=DefaultExperiment(stopTime="10"))
    md.coSimulation.fixedInternalStepSize = 0.01
    # The container answers value reference 0 with its own time.
    md.modelVariables.append(ModelVariable(name="time", causality="independent", variability="continuous",
                                           type="Real"))
    mappings = {}
    for name in ("phi", "w"):
        v = ModelVariable(name=name, causality="output", variability="continuous", type="Real")
        v.initial = "calculated"
        md.modelVariables.append(v)
        mappings[v] = [(pend, variable(pend, name))]
    p = ModelVariable(name="phi_start", causality="parameter", variability="fixed", type="Real", start="0.1")
    p.initial = "exact"
    md.modelVariables.append(p)
    mappings[p] = [(pend, variable(pend, "phi_start"))]
    md.outputs = [Unknown(index=2, variable=md.modelVariables[1]), Unknown(index=3, variable=md.modelVariables[2])]
    md.initialUnknowns = list(md.outputs)
    links = [Connection(pend, [variable(pend, "w", True)], drag, [variable(drag, "w", True)]),
             Connection(drag, [variable(drag, "tau", True)], pend, [variable(pend, "tau_drag", True)])]
    cfg = Configuration(parallelDoStep=False, modelDescription=md, components=[pend, drag], connections=links,
                        variableMappings=mappings)
    stage = out / "stage"
    stage.mkdir(parents=True)
    fmu = out / "PendulumDrag.fmu"
    create_container_fmu(cfg, stage, fmu)
    return fmu


def _fmutool_container(out: Path) -> Path:
    return fmutool_container("core_grasshopper_drag", out)


CONTAINERS = {
    "fmpy": (_fmpy_container, ["phi", "w"], {"phi_start": 0.2}, 0.01, 400),
    "fmu-manipulation-toolbox": (_fmutool_container, ["pendulum.phi", "pendulum.w", "escapement.tau"], {},
                                 0.01, 400),
}


@pytest.fixture(scope="module", params=sorted(CONTAINERS))
def container(request, tmp_path_factory):
    build, outputs, params, h, n = CONTAINERS[request.param]
    return build(tmp_path_factory.mktemp(request.param.replace("-", "_"))), outputs, params, h, n


def _clockwork(fmu: Path, outputs, params, h, n, engine):
    with System({"c": (str(fmu), params)}, [], MasterSettings(step=h, engine=engine),
                record={"c": outputs}) as s:
        assert type(s.master) is (CompiledMaster if engine == "compiled" else Master)
        rec = Recorder(s.master, [("c", o) for o in outputs])
        rec.start()
        s.master.run_until(n * h, rec)
        return rec.columns


def test_both_engines_and_fmpy_agree_on_a_container(container):
    from fmpy import simulate_fmu

    fmu, outputs, params, h, n = container
    python = _clockwork(fmu, outputs, params, h, n, "python")
    compiled = _clockwork(fmu, outputs, params, h, n, "compiled")
    assert python == compiled
    assert len(compiled["time"]) == n + 1
    phi = np.asarray(compiled[f"c.{outputs[0]}"][1:])
    assert (phi > 0).any() and (phi < 0).any()  # it swings
    ref = simulate_fmu(str(fmu), stop_time=n * h, output_interval=h, output=outputs, start_values=params)
    assert len(ref) == n + 1
    for o in outputs:
        assert np.array_equal(ref[o], np.asarray(compiled[f"c.{o}"])), o
