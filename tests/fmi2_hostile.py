"""The FMI 2.0 Co-Simulation test FMU made of tests/data/fmi2/hostile.c (the
FMI 2.0 headers come from the installed fmpy): it logs through bad
componentEnvironments, instance names and formats, and crashes, hangs or
fails in doStep at t_fault as `fault` says (see hostile.c). Its description
and stubs are here; CMake builds it (tests/CMakeLists.txt, tests/c_fmus.py)
as test_fmu("Hostile"), and with other flags as "AbortInit"
(-DCW_ABORT_IN_INSTANTIATE) and "NoUnwind" (no unwind tables)."""

from __future__ import annotations

import re
from pathlib import Path

import fmpy

SOURCE = Path(__file__).parent / "data" / "fmi2" / "hostile.c"

MODEL_DESCRIPTION = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="Hostile" guid="{cw-fmi2-hostile}"
    description="clockwork's FMI 2.0 test FMU that breaks the rules">
  <CoSimulation modelIdentifier="Hostile" canHandleVariableCommunicationStepSize="true"/>
  <DefaultExperiment startTime="0" stopTime="1" stepSize="0.1"/>
  <ModelVariables>
    <ScalarVariable name="x" valueReference="0" causality="output" variability="continuous"><Real/></ScalarVariable>
    <ScalarVariable name="t_fault" valueReference="1" causality="parameter" variability="fixed">
      <Real start="1e300"/></ScalarVariable>
    <ScalarVariable name="fault" valueReference="2" causality="parameter" variability="fixed">
      <Real start="0"/></ScalarVariable>
  </ModelVariables>
  <ModelStructure>
    <Outputs><Unknown index="1"/></Outputs>
  </ModelStructure>
</fmiModelDescription>
"""

_TYPEDEF = re.compile(r"typedef\s+(\w+)\s+(fmi2\w+)TYPE\s*\(([^;]*)\)\s*;", re.S)


def stubs(defined: str) -> str:
    """The FMI 2.0 functions hostile.c leaves out, each failing (fmpy loads
    every symbol), made from the prototypes of fmpy's fmi2FunctionTypes.h."""
    header = (Path(fmpy.__file__).parent / "c-code" / "fmi2FunctionTypes.h").read_text()
    out = []
    for m in _TYPEDEF.finditer(header):
        ret, name, args = m.group(1), m.group(2), " ".join(m.group(3).split())
        if re.search(rf"\b{name}\s*\(", defined):
            continue
        body = {"fmi2Status": "return fmi2Error;", "fmi2Component": "return NULL;", "void": "",
                "fmi2String": 'return "2.0";'}[ret]
        out.append(f"{ret} {name}({args}) {{ {body} }}")
    return "\n".join(out) + "\n"


def sweep_scene(folder: Path, fmu: Path, fault: int, t_faults: list[float], title: str) -> Path:
    """folder/s.toml: a sweep of the hostile FMU over `t_faults`, 1 s in steps of 0.1 s, x recorded."""
    scene = Path(folder) / "s.toml"
    scene.write_text(f"""
[scene]
title = "{title}"
[components.h]
fmu = "{fmu}"
parameters = {{ fault = {fault} }}
[experiment]
stop = "1 s"
[master]
step = "0.1 s"
[record]
outputs = ["h.x"]
[sweep]
axes = [ {{ parameter = "h.t_fault", values = {list(t_faults)!r} }} ]
""")
    return scene
