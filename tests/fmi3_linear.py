"""The FMI 3.0 Co-Simulation test FMU made of tests/data/fmi3/linear.c, with
array variables (the FMI 3.0 headers come from the installed fmpy), for the
master's array tests: dx/dt = A x + B u, y = C x + D u with n = 3 states (a
structural parameter), A (3x3), B (3x2), C (2x3), D (2x2) and x0 (3) array
parameters, an array input u (2) and array outputs y (2) and x (3), a
scalar input w and output s = sum(x) + w, an Int32 array input k (3)
mirrored by the output kk, the first and second derivatives of x and y,
and the faults of failed runs (t_nan, t_fail). See linear.c. CMake builds
it (tests/CMakeLists.txt, tests/c_fmus.py) as test_fmu("fmi3/Linear"), with
-DCW_CRASH_AFTER_T_FAIL -DCW_HOSTILE_LOG as "fmi3/LinearCrash", and with
empty_output_description() as "fmi3/Empty"."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

SOURCE = Path(__file__).parent / "data" / "fmi3" / "linear.c"

MODEL_DESCRIPTION = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="Linear" instantiationToken="{cw-fmi3-linear}"
    description="clockwork's FMI 3.0 test FMU with arrays: dx/dt = A x + B u, y = C x + D u">
  <CoSimulation modelIdentifier="Linear" canHandleVariableCommunicationStepSize="true"
      maxOutputDerivativeOrder="2"/>
  <UnitDefinitions>
    <Unit name="m"><BaseUnit m="1"/></Unit>
    <Unit name="s"><BaseUnit s="1"/></Unit>
  </UnitDefinitions>
  <DefaultExperiment startTime="0" stopTime="2" stepSize="0.1"/>
  <ModelVariables>
    <Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>
    <UInt64 name="n" valueReference="1" causality="structuralParameter" variability="fixed" start="3"
        min="1" max="4"/>
    <Float64 name="A" valueReference="2" causality="parameter" variability="fixed" start="-1 0 0 0 -2 0 0 0 -3">
      <Dimension valueReference="1"/><Dimension valueReference="1"/></Float64>
    <Float64 name="B" valueReference="3" causality="parameter" variability="fixed" start="1 0 0 1 0 0">
      <Dimension valueReference="1"/><Dimension start="2"/></Float64>
    <Float64 name="C" valueReference="4" causality="parameter" variability="fixed" start="1 0 0 0 1 0">
      <Dimension start="2"/><Dimension valueReference="1"/></Float64>
    <Float64 name="D" valueReference="5" causality="parameter" variability="fixed" start="0 0 0 0">
      <Dimension start="2"/><Dimension start="2"/></Float64>
    <Float64 name="x0" valueReference="6" causality="parameter" variability="fixed" start="1 1 1" unit="m">
      <Dimension valueReference="1"/></Float64>
    <Float64 name="u" valueReference="7" causality="input" variability="continuous" start="0 0" unit="m">
      <Dimension start="2"/></Float64>
    <Float64 name="y" valueReference="8" causality="output" variability="continuous" unit="m">
      <Dimension start="2"/></Float64>
    <Float64 name="x" valueReference="9" causality="output" variability="continuous" unit="m">
      <Dimension valueReference="1"/></Float64>
    <Float64 name="t_nan" valueReference="10" causality="parameter" variability="fixed" start="1e300" unit="s"/>
    <Float64 name="t_fail" valueReference="11" causality="parameter" variability="fixed" start="1e300" unit="s"/>
    <Int32 name="k" valueReference="12" causality="input" variability="discrete" start="0 0 0">
      <Dimension start="3"/></Int32>
    <Int32 name="kk" valueReference="13" causality="output" variability="discrete">
      <Dimension start="3"/></Int32>
    <Float64 name="w" valueReference="14" causality="input" variability="continuous" start="0" unit="m"/>
    <Float64 name="s" valueReference="15" causality="output" variability="continuous" unit="m"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="8" dependencies="7"/>
    <Output valueReference="9" dependencies=""/>
    <Output valueReference="13" dependencies="12"/>
    <Output valueReference="15" dependencies="14"/>
    <InitialUnknown valueReference="8" dependencies="6 7"/>
    <InitialUnknown valueReference="9" dependencies="6"/>
    <InitialUnknown valueReference="13" dependencies="12"/>
    <InitialUnknown valueReference="15" dependencies="6 14"/>
  </ModelStructure>
</fmiModelDescription>
"""


def empty_output_description() -> str:
    """MODEL_DESCRIPTION with y, its only output, of a Dimension of size 0
    (x, kk and s made local): test_fmu("fmi3/Empty")."""
    md = MODEL_DESCRIPTION.replace(
        '<Float64 name="y" valueReference="8" causality="output" variability="continuous" unit="m">\n'
        '      <Dimension start="2"/>',
        '<Float64 name="y" valueReference="8" causality="output" variability="continuous" unit="m">\n'
        '      <Dimension start="0"/>')
    for vr in ("9", "13", "15"):
        md = re.sub(rf'(valueReference="{vr}" )causality="output"', r'\1causality="local"', md)
        md = re.sub(rf'\s*<(Output|InitialUnknown) valueReference="{vr}"[^>]*/>', "", md)
    assert '<Dimension start="0"/>' in md and md.count('causality="output"') == 1
    return md


@pytest.fixture(scope="module")
def fmu():
    """The test FMU (built by CMake: tests/CMakeLists.txt)."""
    from cwtest import test_fmu

    return test_fmu("fmi3/Linear")
