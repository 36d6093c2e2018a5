"""The FMI 3.0 Co-Simulation test FMU made of tests/data/fmi3/alltypes.c (the
FMI 3.0 headers come from the installed fmpy), for the master's tests of
every FMI 3.0 variable type: per type T a parameter p_T, an input u_T and an
output y_T that mirrors u_T. See alltypes.c."""

from __future__ import annotations

from pathlib import Path

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


# Array variables (FMI 3.0 <Dimension>) of four types, for the description tests (the C code serves none of them).
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


def defined() -> str:
    """alltypes.c and the names of the functions its NUMBER_ACCESS macro
    defines: the text whose FMI 3.0 functions need no stub. CMake builds the
    FMU (tests/CMakeLists.txt, tests/c_fmus.py) as test_fmu("fmi3/AllTypes"),
    and with the ARRAYS variables in its description as test_fmu("fmi3/Arrays")."""
    return SOURCE.read_text() + "".join(f" fmi3Get{t}( fmi3Set{t}(" for t in _MACRO_TYPES)
