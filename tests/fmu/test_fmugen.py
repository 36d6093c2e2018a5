"""tools/fmugen.py: the generated CW_MODEL and ModelStructure, and the table
errors it refuses before anything is compiled."""

from __future__ import annotations

import re
import shutil
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
MODELS = ROOT / "src_c" / "models"
sys.path.insert(0, str(ROOT / "tools"))

import fmugen  # noqa: E402


@pytest.fixture
def drag(tmp_path) -> Path:
    """A copy of the Drag model folder with the shared tables next to it."""
    models = tmp_path / "models"
    shutil.copytree(MODELS / "Drag", models / "Drag")
    for shared in ("units.toml", "references.toml"):
        shutil.copy(MODELS / shared, models / shared)
    return models / "Drag"


def _edit(path: Path, old: str, new: str):
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))


def _refused(model_dir: Path, *words: str):
    with pytest.raises(fmugen.TableError) as e:
        fmugen.load(model_dir)
    for w in words:
        assert w in str(e.value), str(e.value)


def test_generated_model_definition(tmp_path):
    out = tmp_path / "gen"
    assert fmugen.main([str(MODELS / "GrasshopperEscapement"), str(out)]) == 0
    header = (out / "cw_vars.h").read_text()
    block = header[header.index("#ifndef CW_VARS_TABLE_ONLY"):]
    assert "enum cw_real_state_slot { S_MODE, S_PHI, S_DELTA, CW_N_REAL_STATE };" in block
    assert "enum cw_uint_state_slot { U_RNG, U_RENEWALS, CW_N_UINT_STATE };" in block
    assert "static void commit(cw_instance *inst);" in block
    fields = dict(re.findall(r"^\s+\.(\w+) = (.+),$", block, re.M))
    assert fields["validate"] == "NULL" and fields["do_step"] == "NULL"
    assert fields["commit"] == "commit" and fields["n_uint_state"] == "CW_N_UINT_STATE"
    assert (out / "documentation" / "index.html").exists() and (out / "model.png").exists()


def test_callbacks_must_match_model_c(drag):
    _edit(drag / "model.toml", 'callbacks = ["calc_outputs"]', 'callbacks = ["calc_outputs", "validate"]')
    _refused(drag, "callbacks", "validate", "defines ['calc_outputs']")


def test_callback_names_are_known(drag):
    _edit(drag / "model.toml", 'callbacks = ["calc_outputs"]', 'callbacks = ["calc_output"]')
    _refused(drag, "callbacks must be distinct names")


def test_dependency_declarations_are_checked(drag):
    toml = drag / "model.toml"
    original = toml.read_text()
    _edit(toml, 'depends_on = ["w", "rho_air", "mu_air"]', 'depends_on = ["c1"]')
    _refused(drag, "depends_on 'c1'", "neither an input nor a state")
    toml.write_text(original)
    _edit(toml, 'depends_on = ["w", "rho_air", "mu_air"]', 'depends_on = { w = "linear" }')
    _refused(drag, "dependency kind 'linear'")
    toml.write_text(original)
    _edit(toml, 'initial_depends_on = ["c1", "c2", "bob_radius", "arm", "drag_coefficient", "omega", "w", "rho_air", "mu_air"]', 'initial_depends_on = ["c1", "tau"]')
    _refused(drag, "initial_depends_on 'tau'", "neither an input nor a parameter")


def test_dependencies_are_in_index_order(drag, tmp_path):
    _edit(drag / "model.toml", 'initial_depends_on = ["c1", "c2", "bob_radius", "arm", "drag_coefficient", "omega", "w", "rho_air", "mu_air"]',
          'initial_depends_on = ["mu_air", "w", "c2", "c1"]')
    assert fmugen.main([str(drag), str(tmp_path / "gen")]) == 0
    root = ET.parse(tmp_path / "gen" / "modelDescription.xml").getroot()
    (unknown,) = root.find("ModelStructure/InitialUnknowns")
    deps = [int(k) for k in unknown.get("dependencies").split()]
    assert deps == sorted(deps) and len(deps) == 4
    assert unknown.get("dependenciesKind") == "dependent dependent dependent dependent"


def test_enumerations_states_and_fmi_names(drag, tmp_path):
    """Enumeration variables with their TypeDefinitions, a declared state
    (derivative_of) that an output may depend on, and FMI names that are
    not C identifiers."""
    _edit(drag / "model.toml", "[experiment]", '[types.Mode]\nitems = ["a", "b"]\n\n[experiment]')
    _edit(drag / "model.toml", "step = 0.01", "step = 0.01\ntolerance = 1e-5")
    with open(drag / "model.toml", "a") as f:
        f.write('\n[[variable]]\nname = "mode"\nvr = 30\ntype = "Enumeration"\ndeclared_type = "Mode"\n'
                'causality = "parameter"\nvariability = "fixed"\nstart = 2\ndescription = "m"\n'
                '\n[[variable]]\nname = "q"\nvr = 31\ntype = "Real"\ncausality = "local"\n'
                'variability = "continuous"\ndescription = "state"\n'
                '\n[[variable]]\nname = "der(q)"\nvr = 32\ntype = "Real"\ncausality = "local"\n'
                'variability = "continuous"\nderivative_of = "q"\ndescription = "rate"\n'
                '\n[[variable]]\nname = "out.q"\nvr = 33\ntype = "Real"\ncausality = "output"\n'
                'variability = "continuous"\ndepends_on = ["q"]\ndescription = "q"\n')
    assert fmugen.main([str(drag), str(tmp_path / "gen"), "--fmi2-only"]) == 0
    header = (tmp_path / "gen" / "cw_vars.h").read_text()
    assert "VR_der_q_ = 32," in header and "VR_out_q = 33," in header
    assert '[30] = {"mode", 30, CW_INTEGER,' in header
    root = ET.parse(tmp_path / "gen" / "modelDescription.xml").getroot()
    assert [i.get("name") for i in root.iter("Item")] == ["a", "b"]
    assert root.find("DefaultExperiment").get("tolerance") == "1e-05"
    index = {v.get("name"): k + 1 for k, v in enumerate(root.iter("ScalarVariable"))}
    assert root.find("ModelVariables")[index["der(q)"] - 1].find("Real").get("derivative") == str(index["q"])
    (der,) = root.find("ModelStructure/Derivatives")
    assert der.get("index") == str(index["der(q)"])
    outputs = {u.get("index"): u.get("dependencies") for u in root.find("ModelStructure/Outputs")}
    assert outputs[str(index["out.q"])] == str(index["q"])
    initial = [int(u.get("index")) for u in root.find("ModelStructure/InitialUnknowns")]
    assert initial == sorted(initial) and index["q"] in initial and index["der(q)"] in initial


def test_enumeration_and_state_declarations_are_checked(drag):
    toml = drag / "model.toml"
    original = toml.read_text()
    _edit(toml, 'name = "c1"\nvr = 0\ntype = "Real"', 'name = "c1"\nvr = 0\ntype = "Enumeration"')
    _refused(drag, "declared_type")
    toml.write_text(original)
    _edit(toml, 'name = "c1"\nvr = 0\ntype = "Real"', 'name = "c1"\nvr = 0\ntype = "Real"\nderivative_of = "w"')
    _refused(drag, "derivative_of is for Real local variables")


@pytest.mark.parametrize("kind, variable", [
    ("Enumeration", '[types.Mode]\nitems = ["a"]\n'),
    ("declared states", ""),
])
def test_fmi3_build_refuses_enumerations_and_declared_states(drag, tmp_path, capsys, kind, variable):
    """The FMI 3.0 writer refuses what the fmi3 face cannot serve, in one
    line; --fmi2-only builds the same table (as CMake does for test models)."""
    if kind == "Enumeration":
        _edit(drag / "model.toml", "[experiment]", variable + "\n[experiment]")
        extra = ('\n[[variable]]\nname = "mode"\nvr = 30\ntype = "Enumeration"\ndeclared_type = "Mode"\n'
                 'causality = "parameter"\nvariability = "fixed"\nstart = 1\ndescription = "m"\n')
    else:
        extra = ('\n[[variable]]\nname = "q"\nvr = 31\ntype = "Real"\ncausality = "local"\n'
                 'variability = "continuous"\ndescription = "state"\n'
                 '\n[[variable]]\nname = "der(q)"\nvr = 32\ntype = "Real"\ncausality = "local"\n'
                 'variability = "continuous"\nderivative_of = "q"\ndescription = "rate"\n')
    with open(drag / "model.toml", "a") as fh:
        fh.write(extra)
    assert fmugen.main([str(drag), str(tmp_path / "gen")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "FMI 3.0 build" in err and "FMI 2.0 only" in err
    assert not (tmp_path / "gen" / "fmi3" / "modelDescription.xml").exists()
    assert fmugen.main([str(drag), str(tmp_path / "gen"), "--fmi2-only"]) == 0
    assert not (tmp_path / "gen" / "fmi3").exists()


def test_fmi3_default_experiment_keeps_the_tolerance(drag, tmp_path):
    _edit(drag / "model.toml", "step = 0.01", "step = 0.01\ntolerance = 1e-5")
    assert fmugen.main([str(drag), str(tmp_path / "gen")]) == 0
    md = ET.parse(tmp_path / "gen" / "fmi3" / "modelDescription.xml").getroot()
    assert md.find("DefaultExperiment").get("tolerance") == "1e-05"


def test_every_model_gets_the_fmi3_build(drag, tmp_path):
    """A model folder gives the FMI 3.0 files too: nothing per model to add."""
    out = tmp_path / "gen"
    assert fmugen.main([str(drag), str(out), "--sources", "cw_runtime.c", "cw_fmi2.c", "model.c"]) == 0
    md = ET.parse(out / "fmi3" / "modelDescription.xml").getroot()
    assert md.get("fmiVersion") == "3.0"
    assert md.get("instantiationToken") == ET.parse(out / "modelDescription.xml").getroot().get("guid")
    cs = md.find("CoSimulation")
    assert cs.get("hasEventMode") == "true" and cs.get("mightReturnEarlyFromDoStep") == "false"
    (time,) = [v for v in md.find("ModelVariables") if v.get("causality") == "independent"]
    assert time.get("name") == "time"
    build = ET.parse(out / "fmi3" / "buildDescription.xml").getroot()
    assert [f.get("name") for f in build.iter("SourceFile")] == ["cw_runtime.c", "cw_fmi3.c", "model.c"]
    assert (out / "fmi3" / "documentation" / "index.html").is_file()


def test_early_return_sets_might_return_early(drag, tmp_path):
    _edit(drag / "model.toml", 'callbacks = ["calc_outputs"]',
          'callbacks = ["calc_outputs"]\nearly_return = ["stall"]')
    out = tmp_path / "gen"
    assert fmugen.main([str(drag), str(out)]) == 0
    cs = ET.parse(out / "fmi3" / "modelDescription.xml").getroot().find("CoSimulation")
    assert cs.get("mightReturnEarlyFromDoStep") == "true"
    assert "stall" in (out / "fmi3" / "documentation" / "index.html").read_text()


@pytest.mark.parametrize("value", ['"stall"', "[1]", '[""]'])
def test_early_return_must_be_a_list_of_names(drag, value):
    _edit(drag / "model.toml", 'callbacks = ["calc_outputs"]', f'callbacks = ["calc_outputs"]\nearly_return = {value}')
    _refused(drag, "early_return must be a list of event names")


def test_time_is_the_fmi3_independent_variable(drag):
    _edit(drag / "model.toml", 'name = "c1"', 'name = "time"')
    _refused(drag, "'time' is the FMI 3.0 build's independent variable")


def test_fmi3_dependencies_are_value_references():
    t = fmugen.load(MODELS / "Pendulum")
    md = ET.fromstring(fmugen.generate_xml3(t))
    vr = {v.get("name"): v.get("valueReference") for v in md.find("ModelVariables")}
    (a,) = [o for o in md.find("ModelStructure").iter("Output") if o.get("valueReference") == vr["a"]]
    assert a.get("dependencies").split() == [vr[n] for n in ("tau_escapement", "tau_drag", "tau_coupling",
                                                             "tau_external", "g_factor", "rho_air", "mu_air",
                                                             "temperature")]
    # The torques act through the inertia, which the air's inputs change.
    assert a.get("dependenciesKind").split() == ["dependent"] * 8


STRING_VARIABLE = ('\n[[variable]]\nname = "label"\nvr = 30\ntype = "String"\ncausality = "parameter"\n'
                   'variability = "tunable"\nstart = "a \\"b\\" \\\\ é & <c>"\ndescription = "text"\n')


def test_strings_are_written_escaped_and_fmi2_only(drag, tmp_path, capsys):
    with open(drag / "model.toml", "a") as fh:
        fh.write(STRING_VARIABLE)
    assert fmugen.main([str(drag), str(tmp_path / "gen"), "--fmi2-only"]) == 0
    header = (tmp_path / "gen" / "cw_vars.h").read_text()
    assert r'CW_STRING, CW_PARAMETER, CW_TUNABLE, 0, -HUGE_VAL, HUGE_VAL, 0, 0, "a \"b\" \\ \303\251 & <c>"}' in header
    import fmpy

    md = fmpy.read_model_description(str(tmp_path / "gen" / "modelDescription.xml"))
    label = next(v for v in md.modelVariables if v.name == "label")
    assert (label.type, label.start) == ("String", 'a "b" \\ é & <c>')
    assert fmugen.main([str(drag), str(tmp_path / "gen3")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no String variables" in err and "FMI 2.0 only" in err


@pytest.mark.parametrize("extra", ['min = 0\n', 'unit = "m"\n', None])
def test_a_string_with_a_range_unit_or_number_start_is_refused(drag, extra):
    text = STRING_VARIABLE + (extra or "")
    if extra is None:
        text = text.replace('start = "a', 'start = 1\n#"a')
    with open(drag / "model.toml", "a") as fh:
        fh.write(text)
    _refused(drag, "label", "a String takes a text start value")


def test_a_counted_variable_stands_for_its_elements(drag, tmp_path):
    """count = n: n scalar variables name[1] .. name[n] with consecutive
    value references (TestSink's 1000 inputs)."""
    with open(drag / "model.toml", "a") as f:
        f.write('\n[[variable]]\nname = "extra"\ncount = 3\nvr = 90\ntype = "Real"\ncausality = "input"\n'
                'variability = "continuous"\nstart = 0.0\ndescription = "An element"\n')
    t = fmugen.load(drag)
    extra = [(v["name"], v["vr"]) for v in t["variable"] if v["name"].startswith("extra")]
    assert extra == [("extra[1]", 90), ("extra[2]", 91), ("extra[3]", 92)]
    assert "count" not in t["variable"][-1]
    root = ET.fromstring(fmugen.generate_xml(t, []))
    names = [v.get("name") for v in root.iter("ScalarVariable")]
    assert names[-3:] == ["extra[1]", "extra[2]", "extra[3]"]


@pytest.mark.parametrize("count", ["0", "-2", "1.5", "true", '"3"', "100001"])
def test_a_bad_count_is_refused(drag, count):
    with open(drag / "model.toml", "a") as f:
        f.write(f'\n[[variable]]\nname = "extra"\ncount = {count}\nvr = 90\ntype = "Real"\ncausality = "input"\n'
                'variability = "continuous"\nstart = 0.0\ndescription = "An element"\n')
    _refused(drag, "extra", "count must be a whole number from 1 to 100000")
def test_fmi1_description(tmp_path):
    """The FMI 1.0 build's modelDescription.xml: parameters have variability
    "parameter", an output's DirectDependency names its inputs only (a
    state it depends on is no input), the Capabilities say what the
    runtime offers, event indicators are clockwork's VendorAnnotation
    name-value pairs; fmpy reads it back with the FMI 1.0 schema."""
    import fmpy

    t = fmugen.load(MODELS / "GrasshopperEscapement")
    xml = fmugen.generate_xml1(t)
    md = ET.fromstring(xml)
    assert md.get("fmiVersion") == "1.0" and md.get("modelIdentifier") == "GrasshopperEscapement"
    variables = {v.get("name"): v for v in md.find("ModelVariables")}
    table = {v["name"]: v for v in t["variable"]}
    for name, v in variables.items():
        want = {"parameter": ("parameter", "internal"), "input": (None, "input"),
                "output": (None, "output"), "local": (None, "internal")}[table[name]["causality"]]
        assert v.get("causality") == want[1] and (want[0] is None or v.get("variability") == want[0])
        if table[name]["causality"] == "output":
            inputs = {d for d in table[name].get("depends_on", []) if table.get(d, {}).get("causality") == "input"}
            assert {n.text for n in v.iter("Name")} == inputs
    caps = md.find("Implementation/CoSimulation_StandAlone/Capabilities")
    assert caps.get("canRejectSteps") == "false" and caps.get("canRunAsynchronuously") == "false"
    indicators = [a.get("value") for a in md.iter("Annotation") if a.get("name") == "eventIndicator"]
    assert indicators == [v["name"] for v in sorted(t["variable"], key=lambda v: v["vr"]) if v.get("event_indicator")]
    assert indicators
    path = tmp_path / "modelDescription.xml"
    path.write_text(xml)
    fmpy.read_model_description(str(path), validate=True)
