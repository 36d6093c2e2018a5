"""Builds tests/data/fmi3/alltypes.c into an FMI 3.0 Co-Simulation FMU (the
FMI 3.0 headers come from the installed fmpy), for the master's tests of
every FMI 3.0 variable type: per type T a parameter p_T, an input u_T and an
output y_T that mirrors u_T. See alltypes.c."""

from __future__ import annotations

import os
import shutil
import subprocess
import zipfile
from pathlib import Path

import fmpy
from fmi3_bouncer import stubs

SOURCE = Path(__file__).parent / "data" / "fmi3" / "alltypes.c"

# In the order of alltypes.c's type enum (value references 1 + 3k, 2 + 3k, 3 + 3k).
TYPES = ("Float32", "Float64", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64",
         "Boolean", "String", "Binary", "Enumeration")
# The functions alltypes.c defines through its NUMBER_ACCESS macro.
_MACRO_TYPES = ("Float32", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "UInt64", "Boolean")
_START = {"Boolean": "false", "String": "start", "Binary": "", "Enumeration": "1"}


def _variable(kind: str, name: str, vr: int, causality: str, variability: str, extra: str = "") -> str:
    attrs = f'name="{name}" valueReference="{vr}" causality="{causality}" variability="{variability}"{extra}'
    if kind == "Enumeration":
        attrs += ' declaredType="Mode"'
    if kind in ("String", "Binary"):  # FMI 3.0 gives their start as a child element
        if causality == "output":
            return f"    <{kind} {attrs}/>"
        return f'    <{kind} {attrs}><Start value="{_START[kind]}"/></{kind}>'
    start = "" if causality == "output" else f' start="{_START.get(kind, "0")}"'
    return f"    <{kind} {attrs}{start}/>"


# Array variables (FMI 3.0 <Dimension>), which the master refuses at load.
ARRAYS = ("a_Float64", "a_Int8", "a_Boolean", "a_String")
_ARRAY_ROWS = """    <Float64 name="a_Float64" valueReference="100" causality="output" variability="continuous">
      <Dimension start="3"/></Float64>
    <Int8 name="a_Int8" valueReference="101" causality="parameter" variability="fixed" start="1 2">
      <Dimension start="2"/></Int8>
    <Boolean name="a_Boolean" valueReference="102" causality="local" variability="discrete" initial="exact"
        start="true">
      <Dimension start="1"/></Boolean>
    <String name="a_String" valueReference="103" causality="parameter" variability="fixed">
      <Dimension start="2"/><Start value="x"/><Start value="y"/></String>"""


def model_description(arrays: bool = False) -> str:
    rows = ['    <Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>']
    outputs = []
    for k, kind in enumerate(TYPES):
        discrete = "continuous" if kind in ("Float32", "Float64") else "discrete"
        rows.append(_variable(kind, f"p_{kind}", 1 + 3 * k, "parameter", "fixed"))
        rows.append(_variable(kind, f"u_{kind}", 2 + 3 * k, "input", discrete))
        rows.append(_variable(kind, f"y_{kind}", 3 + 3 * k, "output", discrete))
        outputs.append(f'    <Output valueReference="{3 + 3 * k}" dependencies="{2 + 3 * k}"/>')
    outputs += [f'    <InitialUnknown valueReference="{3 + 3 * k}" dependencies="{2 + 3 * k}"/>'
                for k in range(len(TYPES))]
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="AllTypes" instantiationToken="{{cw-fmi3-alltypes}}"
    description="clockwork's FMI 3.0 test FMU of every variable type">
  <CoSimulation modelIdentifier="AllTypes" canHandleVariableCommunicationStepSize="true"/>
  <TypeDefinitions>
    <EnumerationType name="Mode">
      <Item name="low" value="1"/><Item name="mid" value="2"/><Item name="high" value="3"/>
    </EnumerationType>
  </TypeDefinitions>
  <ModelVariables>
{chr(10).join(rows)}
{_ARRAY_ROWS if arrays else ''}
  </ModelVariables>
  <ModelStructure>
{'    <Output valueReference="100"/>' if arrays else ''}
{chr(10).join(outputs)}
{'    <InitialUnknown valueReference="100"/>' if arrays else ''}
  </ModelStructure>
</fmiModelDescription>
"""


def build(folder: Path, name: str = "AllTypes", arrays: bool = False) -> Path:
    """Compile and zip the FMU into folder/<name>.fmu (with the ARRAYS
    variables when `arrays`); returns its path."""
    cc = shutil.which(os.environ.get("CC", "cc")) or shutil.which("gcc")
    if cc is None:
        raise RuntimeError("no C compiler")
    folder = Path(folder)
    work = folder / f"{name}.build"
    binary = work / "binaries" / fmpy.platform_tuple / "AllTypes.so"
    binary.parent.mkdir(parents=True, exist_ok=True)
    headers = Path(fmpy.__file__).parent / "c-code"
    source = SOURCE.read_text()
    defined = source + "".join(f" fmi3Get{t}( fmi3Set{t}(" for t in _MACRO_TYPES)
    full = work / "alltypes_all.c"
    full.write_text(source + "\n/* generated: the functions left out */\n" + stubs(defined))
    subprocess.run([cc, "-shared", "-fPIC", "-O1", "-std=c99", "-Wall", f"-I{headers}", str(full),
                    "-o", str(binary)], check=True)
    fmu = folder / f"{name}.fmu"
    with zipfile.ZipFile(fmu, "w") as z:
        z.writestr("modelDescription.xml", model_description(arrays))
        z.write(binary, f"binaries/{fmpy.platform_tuple}/AllTypes.so")
    shutil.rmtree(work)
    return fmu
