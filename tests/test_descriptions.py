"""modelDescription.xml under hostile edits: one validation pass for FMI 2.0
and 3.0 (clockwork/fmi/description_check.py), before fmpy reads it.

Each edit is one line on stderr naming the FMU file, modelDescription.xml,
the line, the element and the attribute, exit code 2, for `validate` and
`run`, nothing written; before the pass some were tracebacks (`min="zero"`),
unreadable one-liners (`unreadable modelDescription.xml: 21`) or accepted
without a word (duplicate names, two variables on one valueReference,
`start="many"`, `factor="1_0"` read as 10).
"""

import re
import zipfile
from pathlib import Path

import pytest

from cwtest import FMU_DIR, assert_one_line_error, fmu_file, run_cli

from clockwork.fmi.description_check import check_description

SCENE = ('[scene]\ntitle = "a pendulum"\n[components.pendulum]\nfmu = "{fmu}"\nparameters = {{ Q = 1000 }}\n'
         "[experiment]\nstop = 0.05\n[master]\nstep = 0.01\n")


def _fmu3() -> Path:
    path = FMU_DIR / "fmi3" / "Pendulum.fmu"
    if not path.exists():
        pytest.fail(f"{path} is missing: build the FMUs first (cmake --build build)")
    return path


def _sub(pattern: str, new: str):
    """An edit: the first match of `pattern` in modelDescription.xml becomes `new`."""
    def edit(xml: str) -> str:
        out, n = re.subn(pattern, new, xml, count=1)
        assert n == 1, pattern
        return out
    return edit


# (edit, words of the one line); each run on the FMI 3.0 or the FMI 2.0 Pendulum
FMI3 = {
    "two variables named alike": (_sub(r'name="m" valueReference="1"', 'name="L" valueReference="1"'),
                                  ["Float64 name='L'", "unique variable name", "line"]),
    "two variables on one valueReference": (_sub(r'name="m" valueReference="1"', 'name="m" valueReference="0"'),
                                            ["valueReference='0'", "unique valueReference"]),
    "start=many": (_sub(r'(name="L"[^>]*?)start="1"', r'\1start="many"'), ["Float64 'L'", "start='many'",
                                                                          "expected a number"]),
    "two start values on a scalar": (_sub(r'(name="L"[^>]*?)start="1"', r'\1start="1 2"'),
                                     ["start='1 2'", "expected one value", "no Dimension"]),
    "min=zero on a parameter the scene sets": (_sub(r'(name="Q"[^>]*?)min="0"', r'\1min="zero"'),
                                               ["Float64 'Q'", "min='zero'", "expected a number"]),
    "min above max": (_sub(r'(name="L"[^>]*?)min="1e-06"', r'\1min="1e7"'), ["Float64 'L'", "min <= max"]),
    "Python's number syntax": (_sub(r'(name="L"[^>]*?)max="1000000"', r'\1max="1_000_000"'),
                               ["max='1_000_000'", "expected a number"]),
    "an Int32 out of range": (_sub(r'(name="integrator"[^>]*?)start="0"', r'\1start="3000000000"'),
                              ["Int32 'integrator'", "start='3000000000'", "Int32 value"]),
    "an integer that is a real": (_sub(r'(name="integrator"[^>]*?)max="2"', r'\1max="2.0"'),
                                  ["max='2.0'", "expected an integer"]),
    "an Output naming no variable": (_sub(r'<Output valueReference="20"', '<Output valueReference="99"'),
                                     ["Output valueReference='99'", "99 is not the valueReference"]),
    "dependencies naming no variable": (_sub(r'dependencies="10 11', 'dependencies="10 99'),
                                        ["Output", "dependencies=", "99 is not"]),
    "a display unit factor of 0": (_sub(r'name="deg" factor="57.29577951308232"', 'name="deg" factor="0"'),
                                   ["DisplayUnit 'deg'", "factor='0'", "other than 0"]),
    "a base unit factor in Python's syntax": (_sub(r'<BaseUnit rad="1"/>', '<BaseUnit rad="1" factor="1_0"/>'),
                                              ["BaseUnit", "factor='1_0'"]),
    "a valueReference that is no number": (_sub(r'name="m" valueReference="1"', 'name="m" valueReference="one"'),
                                           ["valueReference='one'", "expected an integer"]),
    "no valueReference": (_sub(r'name="m" valueReference="1"', 'name="m"'),
                          ["Float64 'm'", "valueReference", "missing required attribute"]),
    "an unknown declared type": (_sub(r'name="m" valueReference="1"', 'name="m" valueReference="1" declaredType="X"'),
                                 ["declaredType='X'", "TypeDefinitions"]),
    "an unknown variable element": (_sub(r'<Float64 name="w_start"', '<Float65 name="w_start"'),
                                    ["Float65", "expected a variable element"]),
    "a derivative order in Python's syntax": (_sub(r'maxOutputDerivativeOrder="2"', 'maxOutputDerivativeOrder="1_0"'),
                                              ["CoSimulation", "maxOutputDerivativeOrder='1_0'"]),
    "a 4 MiB value": (_sub(r'(name="L"[^>]*?)min="1e-06"', r'\1min="' + "9" * (4 << 20) + '"'),
                      ["Float64 'L'", "min <= max", "characters"]),
    "a 4 MiB number that is none": (_sub(r'(name="L"[^>]*?)min="1e-06"', r'\1min="' + "x" * (4 << 20) + '"'),
                                    ["Float64 'L'", "min='xxx", "characters"]),
}

FMI2 = {
    "two variables named alike": (_sub(r'name="m" valueReference="1"', 'name="L" valueReference="1"'),
                                  ["ScalarVariable name='L'", "unique variable name"]),
    "start=many": (_sub(r'(<Real unit="m" min="1e-06" max="1000000") start="1"', r'\1 start="many"'),
                   ["Real", "start='many'", "expected a number"]),
    "min=zero on a parameter the scene sets": (_sub(r'<Real min="0" max="1000000000000000"',
                                                    '<Real min="zero" max="1000000000000000"'),
                                               ["Real", "min='zero'"]),
    "Python's number syntax": (_sub(r'<Real unit="m" min="1e-06"', '<Real unit="m" min="1_0"'),
                               ["min='1_0'", "expected a number"]),
    "an Unknown naming no variable": (_sub(r'<Unknown index="21"', '<Unknown index="99"'),
                                      ["ModelStructure/Outputs/Unknown", "index='99'",
                                       "99 is not an index of a variable in ModelVariables (1 to 34)"]),
    "dependencies naming no variable": (_sub(r'dependencies="11 12', 'dependencies="11 0'),
                                        ["ModelStructure/Outputs/Unknown", "0 is not an index"]),
    "no type element": (_sub(r'<Real unit="kg" min="1e-09" max="1000000000" start="1"/>', ''),
                        ["ScalarVariable 'm'", "expected one type element"]),
    "two type elements": (_sub(r'(<Real unit="kg" min="1e-09" max="1000000000" start="1"/>)', r'\1<Integer/>'),
                          ["ScalarVariable 'm'", "expected one type element", "found 2"]),
    "an Integer out of range": (_sub(r'<Integer min="0" max="2" start="0"/>',
                                     '<Integer min="0" max="2" start="2147483648"/>'),
                                ["Integer", "start='2147483648'", "Integer value"]),
    "a unit factor of 0": (_sub(r'name="deg" factor="57.29577951308232"', 'name="deg" factor="0"'),
                           ["DisplayUnit 'deg'", "factor='0'"]),
    "a tolerance that is no number": (_sub(r'(<CoSimulation)', r'<DefaultExperiment tolerance="fine"/>\1'),
                                      ["DefaultExperiment", "tolerance='fine'"]),
}


def _edited(tmp_path: Path, src: Path, edit) -> Path:
    fmu = tmp_path / "Edited.fmu"
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(fmu, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                data = edit(data.decode()).encode()
            zout.writestr(item, data)
    return fmu


CASES = [pytest.param(3, c, id=f"fmi3-{c}") for c in FMI3] + [pytest.param(2, c, id=f"fmi2-{c}") for c in FMI2]


@pytest.mark.parametrize("version, case", CASES)
def test_a_hostile_description_is_one_line_exit_2(tmp_path, capsys, version, case):
    edit, needles = (FMI3 if version == 3 else FMI2)[case]
    fmu = _edited(tmp_path, _fmu3() if version == 3 else fmu_file("Pendulum"), edit)
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE.format(fmu=fmu))
    out = tmp_path / "out"
    for cmd in (["validate", scene], ["run", scene, "--out", out, "--no-progress"], ["info", fmu]):
        rc, _, err = run_cli(capsys, cmd)
        assert_one_line_error(rc, err, "Edited.fmu: modelDescription.xml: line ", *needles)
        assert len(err) < 1000, len(err)
    assert not out.exists()


def test_a_4_mib_model_identifier_is_echoed_shortened(tmp_path, capsys):
    fmu = _edited(tmp_path, fmu_file("Pendulum"), lambda xml: xml.replace('modelIdentifier="Pendulum"',
                                                                          f'modelIdentifier="{"x/" * (2 << 20)}"'))
    rc, _, err = run_cli(capsys, ["info", fmu])
    assert_one_line_error(rc, err, "Edited.fmu", "modelIdentifier", "characters", "file name")
    assert len(err) < 1000, len(err)


# Valid by the FMI 2.0 and 3.0 schemas (a unit's and a type's name is a required
# xs:normalizedString, which may be empty): PythonFMU writes <Unit name="">.
LEGAL = {
    "an empty unit name": _sub(r'<Unit name="rad">', '<Unit name=""><BaseUnit/></Unit><Unit name="rad">'),
    "an empty unit name used by a variable": lambda xml: _sub(r'<Unit name="rad">', '<Unit name=""/><Unit name="rad">')(
        xml.replace('unit="kg"', 'unit=""', 1)),
    "an empty type name": lambda xml: _sub(r"<UnitDefinitions>", '<TypeDefinitions><SimpleType name=""><Real/>'
                                           "</SimpleType></TypeDefinitions><UnitDefinitions>")(xml),
}
LEGAL3 = {
    "an empty unit name": LEGAL["an empty unit name"],
    "an empty unit name used by a variable": LEGAL["an empty unit name used by a variable"],
    "an empty type name": _sub(r"<UnitDefinitions>", '<TypeDefinitions><Float64Type name=""/></TypeDefinitions>'
                                                     "<UnitDefinitions>"),
}


@pytest.mark.parametrize("version, case", [(2, c) for c in LEGAL] + [(3, c) for c in LEGAL3])
def test_what_the_schema_allows_is_accepted(tmp_path, capsys, version, case):
    edit = (LEGAL if version == 2 else LEGAL3)[case]
    fmu = _edited(tmp_path, _fmu3() if version == 3 else fmu_file("Pendulum"), edit)
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE.format(fmu=fmu))
    for cmd in (["validate", scene], ["info", fmu], ["run", scene, "--out", tmp_path / "out", "--no-progress"]):
        rc, _, err = run_cli(capsys, cmd)
        assert rc == 0, (cmd[0], err)


def test_aliases_by_value_reference_stay_allowed_in_fmi2(tmp_path, capsys):
    """FMI 2.0 makes variables of one type on one valueReference aliases; FMI 3.0 has Alias elements instead."""
    edit = _sub(r'<ScalarVariable name="m" valueReference="1"', '<ScalarVariable name="m" valueReference="0"')
    fmu = _edited(tmp_path, fmu_file("Pendulum"), edit)
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE.format(fmu=fmu))
    rc, _, err = run_cli(capsys, ["validate", scene])
    assert rc == 0, err


def test_every_description_the_project_builds_passes():
    fmus = sorted(FMU_DIR.glob("*.fmu")) + sorted((FMU_DIR / "fmi3").glob("*.fmu"))
    assert len(fmus) >= 14
    for fmu in fmus:
        with zipfile.ZipFile(fmu) as z:
            check_description(z.read("modelDescription.xml"))
