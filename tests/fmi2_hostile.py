"""Builds tests/data/fmi2/hostile.c into an FMI 2.0 Co-Simulation FMU (the
FMI 2.0 headers come from the installed fmpy) that logs through bad
componentEnvironments, instance names and formats, and crashes, hangs or
fails in doStep at t_fault as `fault` says (see hostile.c)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import zipfile
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


def build(folder: Path, name: str = "Hostile", cflags: tuple[str, ...] = ()) -> Path:
    """Compile and zip the FMU into folder/<name>.fmu; returns its path."""
    cc = shutil.which(os.environ.get("CC", "cc")) or shutil.which("gcc")
    if cc is None:
        raise RuntimeError("no C compiler")
    folder = Path(folder)
    work = folder / f"{name}.build"
    binary = work / "binaries" / "linux64" / "Hostile.so"
    binary.parent.mkdir(parents=True, exist_ok=True)
    source = SOURCE.read_text()
    full = work / "Hostile_all.c"
    full.write_text(source + "\n/* generated: the functions left out */\n" + stubs(source))
    headers = Path(fmpy.__file__).parent / "c-code"
    subprocess.run([cc, "-shared", "-fPIC", "-O1", "-std=gnu99", *cflags, f"-I{headers}", str(full),
                    "-o", str(binary)], check=True)
    fmu = folder / f"{name}.fmu"
    with zipfile.ZipFile(fmu, "w") as z:
        z.writestr("modelDescription.xml", MODEL_DESCRIPTION)
        z.write(binary, "binaries/linux64/Hostile.so")
    shutil.rmtree(work)
    return fmu


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
