"""The FMI 3.0 Co-Simulation test FMU made of tests/data/fmi3/bouncer.c (the
FMI 3.0 headers come from the installed fmpy), for the master's FMI 3.0
tests: event mode, early return, time events, terminateSimulation, FMU
state, an event indicator. See bouncer.c for the model; its description
and the stubs of every FMI 3.0 function a C test FMU leaves out are here,
and CMake builds it (tests/CMakeLists.txt, tests/c_fmus.py)."""

from __future__ import annotations

import re
from pathlib import Path

import fmpy

SOURCE = Path(__file__).parent / "data" / "fmi3" / "bouncer.c"

MODEL_DESCRIPTION = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="Bouncer" instantiationToken="{{cw-fmi3-bouncer}}"
    description="clockwork's FMI 3.0 test FMU">
  <CoSimulation modelIdentifier="Bouncer" canHandleVariableCommunicationStepSize="true"
      canGetAndSetFMUState="true" maxOutputDerivativeOrder="1"
      hasEventMode="{event_mode}" mightReturnEarlyFromDoStep="{early}"/>
  <ModelVariables>
    <Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>
    <Float64 name="v0" valueReference="1" causality="parameter" variability="fixed" start="1"/>
    <Float64 name="period" valueReference="2" causality="parameter" variability="fixed" start="0.25"/>
    <Float64 name="threshold" valueReference="3" causality="parameter" variability="fixed" start="0.5"/>
    <Float64 name="u" valueReference="4" causality="input" variability="continuous" start="0"/>
    <Float64 name="x" valueReference="5" causality="output" variability="continuous" initial="exact" start="0"/>
    <Float64 name="n" valueReference="6" causality="output" variability="discrete" initial="exact" start="0"/>
    <Float64 name="bounces" valueReference="7" causality="output" variability="discrete" initial="exact" start="0"/>
    <Float64 name="z" valueReference="8" causality="output" variability="continuous"/>
    <Int32 name="n_stop" valueReference="9" causality="parameter" variability="fixed" start="0"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="5" dependencies=""/>
    <Output valueReference="6" dependencies=""/>
    <Output valueReference="7" dependencies=""/>
    <Output valueReference="8" dependencies=""/>
    <InitialUnknown valueReference="8" dependencies="3"/>
  </ModelStructure>
  {annotation}
</fmiModelDescription>
"""

INDICATOR = """<VendorAnnotations><Tool name="clockwork"><EventIndicators><Indicator name="z"/></EventIndicators>
  </Tool></VendorAnnotations>"""


_TYPEDEF = re.compile(r"typedef\s+([\w\s\*]+?)\s*\*?\s*(fmi3\w+)TYPE\s*\(([^;]*)\)\s*;", re.S)


def stubs(defined: str) -> str:
    """The FMI 3.0 functions bouncer.c leaves out, each failing (fmpy loads
    every symbol), made from the prototypes of fmpy's fmi3FunctionTypes.h."""
    header = (Path(fmpy.__file__).parent / "c-code" / "fmi3FunctionTypes.h").read_text()
    out = []
    for m in _TYPEDEF.finditer(header):
        ret, name, args = m.group(1).strip(), m.group(2), " ".join(m.group(3).split())
        if re.search(rf"\b{name}\s*\(", defined):
            continue
        body = {"fmi3Status": "return fmi3Error;", "fmi3Instance": "return NULL;", "void": "",
                "const char": 'return "3.0";'}[ret]
        out.append(f"{ret}{'*' if ret == 'const char' else ''} {name}({args}) {{ {body} }}")
    return "\n".join(out) + "\n"


def description(event_mode: bool = True, early_return: bool = True, indicator: bool = False) -> str:
    """The model description: hasEventMode, mightReturnEarlyFromDoStep and
    the event indicator annotation as asked. CMake builds the four variants
    the tests use (tests/c_fmus.py): test_fmu("fmi3/Early") (the defaults),
    "fmi3/Inside" (neither event mode nor early return), "fmi3/Indicator"
    (with the indicator z) and "fmi3/Refusing" (no early return, and a binary
    built with -DCW_REFUSE_EVENT_MODE that refuses eventModeUsed at
    instantiation whatever the description declares)."""
    return MODEL_DESCRIPTION.format(event_mode=str(event_mode).lower(), early=str(early_return).lower(),
                                    annotation=INDICATOR if indicator else "")
