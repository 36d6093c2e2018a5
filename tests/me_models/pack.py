"""Packs a Model Exchange test FMU: the model's table (<Name>.toml) as an
FMI 1.0, 2.0 or 3.0 modelDescription.xml, zipped with the binary CMake built.

    python pack.py <Name>.toml 1|2|3 <binary> <out.fmu>

FMI 1.0 has no ModelStructure: a state's derivative is named der(<state>)
there (the convention importers read the states from), and an output's
inputs are its DirectDependency.

The table: [model] name, guid, description, stop, tolerance (optional),
needs_completed (fmi2CompletedIntegratorStep asks for events), states and
derivatives (variable names, in ModelStructure order), indicators (FMI
3.0's EventIndicator variables; their count is FMI 2.0's
numberOfEventIndicators); one [[variable]] per variable: name, vr, type
(Real, Integer, Boolean), causality, variability, initial, start,
depends_on (an output's inputs).
"""

from __future__ import annotations

import sys
import tomllib
import zipfile
from pathlib import Path
from xml.sax.saxutils import quoteattr

FMI3_TYPES = {"Real": "Float64", "Integer": "Int32", "Boolean": "Boolean"}


def _attrs(**kw) -> str:
    return "".join(f" {k}={quoteattr(str(v))}" for k, v in kw.items() if v is not None)


def _start(v: dict) -> str | None:
    if "start" not in v:
        return None
    x = v["start"]
    return ("true" if x else "false") if v["type"] == "Boolean" else repr(x)


def fmi2(table: dict) -> str:
    model, variables = table["model"], table["variable"]
    index = {v["name"]: k + 1 for k, v in enumerate(variables)}
    derivative_of = dict(zip(model["derivatives"], model["states"]))
    lines = [f'<?xml version="1.0" encoding="UTF-8"?>',
             f'<fmiModelDescription{_attrs(fmiVersion="2.0", modelName=model["name"], guid=model["guid"])}'
             f'{_attrs(description=model["description"], numberOfEventIndicators=len(model["indicators"]))}>',
             f'  <ModelExchange{_attrs(modelIdentifier=model["name"], canGetAndSetFMUstate="true")}'
             f'{_attrs(completedIntegratorStepNotNeeded="false" if model.get("needs_completed") else "true")}/>',
             f'  <DefaultExperiment{_attrs(startTime=0.0, stopTime=model["stop"], tolerance=model.get("tolerance"))}/>',
             "  <ModelVariables>"]
    for v in variables:
        der = derivative_of.get(v["name"])
        lines.append(f'    <ScalarVariable{_attrs(name=v["name"], valueReference=v["vr"], causality=v["causality"])}'
                     f'{_attrs(variability=v["variability"], initial=v.get("initial"))}>')
        lines.append(f'      <{v["type"]}{_attrs(start=_start(v), derivative=index[der] if der else None)}/>')
        lines.append("    </ScalarVariable>")
    lines += ["  </ModelVariables>", "  <ModelStructure>"]
    outputs = [v for v in variables if v["causality"] == "output"]
    if outputs:
        lines.append("    <Outputs>")
        lines += [f'      <Unknown{_attrs(index=index[v["name"]])}'
                  f'{_attrs(dependencies=" ".join(str(index[d]) for d in v.get("depends_on", [])))}/>'
                  for v in outputs]
        lines.append("    </Outputs>")
    if model["derivatives"]:  # the schema wants an Unknown in a Derivatives element
        lines.append("    <Derivatives>")
        lines += [f'      <Unknown{_attrs(index=index[d])}/>' for d in model["derivatives"]]
        lines.append("    </Derivatives>")
    initial = sorted({index[v["name"]] for v in variables
                      if v.get("initial") in ("calculated", "approx")
                      and (v["causality"] == "output" or v["name"] in model["states"]
                           or v["name"] in model["derivatives"])})
    lines.append("    <InitialUnknowns>")
    lines += [f'      <Unknown{_attrs(index=k)}/>' for k in initial]
    lines += ["    </InitialUnknowns>", "  </ModelStructure>", "</fmiModelDescription>", ""]
    return "\n".join(lines)


FMI1_VARIABILITY = {"fixed": "parameter", "tunable": "parameter"}
FMI1_CAUSALITY = {"local": "internal", "parameter": "internal", "calculatedParameter": "internal"}


def fmi1(table: dict) -> str:
    model, variables = table["model"], table["variable"]
    # A derivative is renamed der(<state>); one that is itself a state keeps its
    # name, and der(<state>) is written as its alias (as Dymola writes them).
    der_names = {d: f"der({s})" for s, d in zip(model["states"], model["derivatives"]) if d not in model["states"]}
    aliases = {d: f"der({s})" for s, d in zip(model["states"], model["derivatives"]) if d in model["states"]}
    named = {v["name"]: der_names.get(v["name"], v["name"]) for v in variables}
    lines = [f'<?xml version="1.0" encoding="UTF-8"?>',
             f'<fmiModelDescription{_attrs(fmiVersion="1.0", modelName=model["name"], modelIdentifier=model["name"])}'
             f'{_attrs(guid=model["guid"], description=model["description"])}'
             f'{_attrs(numberOfContinuousStates=len(model["states"]))}'
             f'{_attrs(numberOfEventIndicators=len(model["indicators"]))}>',
             f'  <DefaultExperiment{_attrs(startTime=0.0, stopTime=model["stop"], tolerance=model.get("tolerance"))}/>',
             "  <ModelVariables>"]
    for v in variables:
        variability = FMI1_VARIABILITY.get(v["variability"], v["variability"])
        causality = FMI1_CAUSALITY.get(v["causality"], v["causality"])
        # FMI 1.0 gives a start to what FMI 2.0 calls exact or approx (fixed="false": a guess).
        start = _start(v) if v.get("initial") in (None, "exact", "approx") else None
        fixed = "false" if start is not None and v.get("initial") == "approx" else None
        lines.append(f'    <ScalarVariable{_attrs(name=named[v["name"]], valueReference=v["vr"])}'
                     f'{_attrs(variability=variability, causality=causality)}>')
        lines.append(f'      <{v["type"]}{_attrs(start=start, fixed=fixed)}/>')
        if v["causality"] == "output" and "depends_on" in v:
            lines.append("      <DirectDependency>")
            lines += [f"        <Name>{named[d]}</Name>" for d in v["depends_on"]]
            lines.append("      </DirectDependency>")
        lines.append("    </ScalarVariable>")
        if v["name"] in aliases:
            lines.append(f'    <ScalarVariable{_attrs(name=aliases[v["name"]], valueReference=v["vr"], alias="alias")}'
                         f'{_attrs(variability=variability, causality="internal")}>')
            lines.append(f'      <{v["type"]}/>')
            lines.append("    </ScalarVariable>")
    lines += ["  </ModelVariables>", "</fmiModelDescription>", ""]
    return "\n".join(lines)


def fmi3(table: dict) -> str:
    model, variables = table["model"], table["variable"]
    vr = {v["name"]: v["vr"] for v in variables}
    derivative_of = dict(zip(model["derivatives"], model["states"]))
    lines = [f'<?xml version="1.0" encoding="UTF-8"?>',
             f'<fmiModelDescription{_attrs(fmiVersion="3.0", modelName=model["name"])}'
             f'{_attrs(instantiationToken=model["guid"], description=model["description"])}>',
             f'  <ModelExchange{_attrs(modelIdentifier=model["name"], canGetAndSetFMUState="true")}'
             f'{_attrs(needsCompletedIntegratorStep="true" if model.get("needs_completed") else "false")}/>',
             f'  <DefaultExperiment{_attrs(startTime=0.0, stopTime=model["stop"], tolerance=model.get("tolerance"))}/>',
             "  <ModelVariables>",
             '    <Float64 name="time" valueReference="0" causality="independent" variability="continuous"/>']
    for v in variables:
        der = derivative_of.get(v["name"])
        lines.append(f'    <{FMI3_TYPES[v["type"]]}{_attrs(name=v["name"], valueReference=v["vr"])}'
                     f'{_attrs(causality=v["causality"], variability=v["variability"], initial=v.get("initial"))}'
                     f'{_attrs(start=_start(v), derivative=vr[der] if der else None)}/>')
    lines += ["  </ModelVariables>", "  <ModelStructure>"]
    lines += [f'    <Output{_attrs(valueReference=v["vr"])}'
              f'{_attrs(dependencies=" ".join(str(vr[d]) for d in v.get("depends_on", [])))}/>'
              for v in variables if v["causality"] == "output"]
    lines += [f'    <ContinuousStateDerivative{_attrs(valueReference=vr[d])}/>' for d in model["derivatives"]]
    initial = sorted({v["vr"] for v in variables
                      if v.get("initial") in ("calculated", "approx")
                      and (v["causality"] == "output" or v["name"] in model["states"]
                           or v["name"] in model["derivatives"])})
    lines += [f'    <InitialUnknown{_attrs(valueReference=k)}/>' for k in initial]
    lines += [f'    <EventIndicator{_attrs(valueReference=vr[z])}/>' for z in model["indicators"]]
    lines += ["  </ModelStructure>", "</fmiModelDescription>", ""]
    return "\n".join(lines)


def main(argv: list[str]) -> None:
    table_path, version, binary, out = argv
    table = tomllib.loads(Path(table_path).read_text())
    name = table["model"]["name"]
    xml = {"1": fmi1, "2": fmi2, "3": fmi3}[version](table)
    folder = "x86_64-linux" if version == "3" else "linux64"
    out = Path(out)
    part = out.with_suffix(".part")
    with zipfile.ZipFile(part, "w") as z:
        z.writestr("modelDescription.xml", xml)
        z.write(binary, f"binaries/{folder}/{name}.so")
    part.replace(out)


if __name__ == "__main__":
    main(sys.argv[1:])
