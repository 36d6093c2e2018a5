"""The model descriptions of the clocked FMI 3.0 test FMUs built from
tests/data/fmi3/clocked.c (Ticker, EarlyTicker, Counter, Sampler:
Co-Simulation with Event Mode; Partitions: Scheduled Execution) for
tests/test_clocks.py; CMake builds them (tests/CMakeLists.txt, through
tests/c_fmus.py) into build/test-fmus/fmi3. See clocked.c for the models."""

from __future__ import annotations

from pathlib import Path

SOURCE = Path(__file__).parent / "data" / "fmi3" / "clocked.c"

HEAD = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="{name}" instantiationToken="{{cw-clocked-{name}}}"
    description="clockwork's clocked FMI 3.0 test FMU">
  {interface}
  <DefaultExperiment startTime="0" stopTime="1" stepSize="0.1"/>
  <ModelVariables>
    <Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>
"""
CS = ('<CoSimulation modelIdentifier="{name}" canHandleVariableCommunicationStepSize="true" hasEventMode="true" '
      'mightReturnEarlyFromDoStep="{early}" canGetAndSetFMUState="true"/>')
SE = '<ScheduledExecution modelIdentifier="{name}" canGetAndSetFMUState="true"/>'

VARIABLES = {
    "Ticker": """
    <Clock name="tick" valueReference="1" causality="output" intervalVariability="triggered"/>
    <Float64 name="period" valueReference="10" causality="parameter" variability="fixed" start="0.1"/>
    <Float64 name="x" valueReference="11" causality="output" variability="continuous"/>
    <Float64 name="announce" valueReference="12" causality="parameter" variability="fixed" start="1"/>
    <Int32 name="n" valueReference="20" causality="output" variability="discrete" clocks="1"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="1"/>
    <Output valueReference="11" dependencies=""/>
    <Output valueReference="20" dependencies="1"/>
    <InitialUnknown valueReference="1"/>
    <InitialUnknown valueReference="11" dependencies=""/>
  </ModelStructure>""",
    "Counter": """
    <Clock name="tooth" valueReference="1" causality="input" intervalVariability="triggered"/>
    <Float64 name="last" valueReference="12" causality="output" variability="discrete" clocks="1"/>
    <Float64 name="total" valueReference="13" causality="output" variability="discrete"/>
    <Int32 name="count" valueReference="20" causality="output" variability="discrete" clocks="1"/>
    <Int32 name="step_by" valueReference="21" causality="input" variability="discrete" start="1" clocks="1"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="12" dependencies="1"/>
    <Output valueReference="13" dependencies=""/>
    <Output valueReference="20" dependencies="1 21"/>
    <InitialUnknown valueReference="13" dependencies=""/>
  </ModelStructure>""",
    "Sampler": """
    <Clock name="sample" valueReference="1" causality="input" intervalVariability="constant"
        intervalDecimal="0.1" shiftDecimal="0.05"/>
    <Clock name="alarm" valueReference="2" causality="input" intervalVariability="countdown"/>
    <Clock name="beat" valueReference="3" causality="input" intervalVariability="changing"/>
    <Float64 name="alarm_time" valueReference="12" causality="output" variability="discrete" clocks="2"/>
    <Int32 name="samples" valueReference="20" causality="output" variability="discrete" clocks="1"/>
    <Int32 name="alarms" valueReference="21" causality="output" variability="discrete" clocks="2"/>
    <Int32 name="beats" valueReference="22" causality="output" variability="discrete" clocks="3"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="12" dependencies="2"/>
    <Output valueReference="20" dependencies="1"/>
    <Output valueReference="21" dependencies="2"/>
    <Output valueReference="22" dependencies="3"/>
  </ModelStructure>""",
    "Partitions": """
    <Clock name="fast" valueReference="1" causality="input" intervalVariability="constant" intervalDecimal="0.1"
        priority="1"/>
    <Clock name="slow" valueReference="2" causality="input" intervalVariability="constant" intervalDecimal="0.3"
        priority="2"/>
    <Clock name="later" valueReference="3" causality="input" intervalVariability="countdown" priority="3"
        clocks="1"/>
    <Clock name="every3" valueReference="4" causality="output" intervalVariability="triggered" clocks="1"/>
    <Int32 name="order" valueReference="20" causality="output" variability="discrete"/>
    <Int32 name="fast_n" valueReference="21" causality="output" variability="discrete" clocks="1"/>
    <Int32 name="slow_n" valueReference="22" causality="output" variability="discrete" clocks="2"/>
    <Int32 name="later_n" valueReference="23" causality="output" variability="discrete" clocks="3"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="4" dependencies="1"/>
    <Output valueReference="20" dependencies=""/>
    <Output valueReference="21" dependencies="1"/>
    <Output valueReference="22" dependencies="2"/>
    <Output valueReference="23" dependencies="3"/>
    <InitialUnknown valueReference="20" dependencies=""/>
  </ModelStructure>""",
}


def description(name: str, early_return: bool = False) -> str:
    """The modelDescription.xml of the clocked test FMU `name` (its modelIdentifier)."""
    interface = (SE if name == "Partitions" else CS).format(name=name, early=str(early_return).lower())
    return HEAD.format(name=name, interface=interface) + VARIABLES[name] + "\n</fmiModelDescription>\n"
