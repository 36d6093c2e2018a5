"""The FMI 2.0 and FMI 3.0 Co-Simulation test FMUs made of
tests/data/strict/strict.c: an FMU that enforces the call sequence (a get after a set
without a step in Step Mode returns an error and logs why): y = gain * u +
offset + slope * time, y with direct feedthrough from u, FMU state. The
headers come from the installed fmpy. `declares`: the description says, in
clockwork's annotation, that outputs may be read after inputs are set (a
false claim for this FMU: the tests use it to show that the annotation is
what the master follows)."""

from __future__ import annotations

from pathlib import Path

SOURCE = Path(__file__).parent / "data" / "strict" / "strict.c"

VARIABLES2 = """
    <ScalarVariable name="u" valueReference="1" causality="input" variability="continuous"><Real start="0"/></ScalarVariable>
    <ScalarVariable name="y" valueReference="2" causality="output" variability="continuous"><Real/></ScalarVariable>
    <ScalarVariable name="gain" valueReference="3" causality="parameter" variability="fixed"><Real start="1"/></ScalarVariable>
    <ScalarVariable name="offset" valueReference="4" causality="parameter" variability="fixed"><Real start="0"/></ScalarVariable>
    <ScalarVariable name="slope" valueReference="5" causality="parameter" variability="fixed"><Real start="0"/></ScalarVariable>
"""

DESCRIPTION2 = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="Strict" guid="{{cw-strict}}"
    description="clockwork's test FMU that enforces FMI 2.0's call sequence">
  <CoSimulation modelIdentifier="Strict" canHandleVariableCommunicationStepSize="true"
      canGetAndSetFMUstate="true"/>
  <DefaultExperiment startTime="0" stopTime="1" stepSize="0.01"/>
  {annotation}
  <ModelVariables>{variables}  </ModelVariables>
  <ModelStructure>
    <Outputs><Unknown index="2" dependencies="1" dependenciesKind="dependent"/></Outputs>
    <InitialUnknowns><Unknown index="2" dependencies="1 3 4 5"/></InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>
"""

DESCRIPTION3 = """<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="3.0" modelName="Strict" instantiationToken="{{cw-strict}}"
    description="clockwork's test FMU that enforces FMI 3.0's Step Mode call sequence">
  <CoSimulation modelIdentifier="Strict" canHandleVariableCommunicationStepSize="true"
      canGetAndSetFMUState="true"/>
  <DefaultExperiment startTime="0" stopTime="1" stepSize="0.01"/>
  <ModelVariables>
    <Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>
    <Float64 name="u" valueReference="1" causality="input" variability="continuous" start="0"/>
    <Float64 name="y" valueReference="2" causality="output" variability="continuous"/>
    <Float64 name="gain" valueReference="3" causality="parameter" variability="fixed" start="1"/>
    <Float64 name="offset" valueReference="4" causality="parameter" variability="fixed" start="0"/>
    <Float64 name="slope" valueReference="5" causality="parameter" variability="fixed" start="0"/>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="2" dependencies="1" dependenciesKind="dependent"/>
    <InitialUnknown valueReference="2" dependencies="1 3 4 5"/>
  </ModelStructure>
  {annotation}
</fmiModelDescription>
"""

CLAIM2 = ('<VendorAnnotations><Tool name="clockwork"><Capabilities outputsAfterInputs="true"/></Tool>'
          '</VendorAnnotations>')
CLAIM3 = '<Annotations><Annotation type="clockwork"><Capabilities outputsAfterInputs="true"/></Annotation></Annotations>'


def description(version: int = 2, declares: bool = False) -> str:
    """The FMI 2.0 or 3.0 model description, with the false claim when
    `declares`. CMake builds strict.c with it (tests/CMakeLists.txt,
    tests/c_fmus.py): test_fmu("Strict2"), test_fmu("Claims") (FMI 2.0,
    declares) and test_fmu("fmi3/Strict3") (strict.c with -DCW_FMI3)."""
    if version == 3:
        return DESCRIPTION3.format(annotation=CLAIM3 if declares else "")
    return DESCRIPTION2.format(annotation=CLAIM2 if declares else "", variables=VARIABLES2)
