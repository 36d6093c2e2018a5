"""`clockwork run | validate | info | export-scene X.fmu`: an FMU alone, with its
DefaultExperiment and fmpy's defaults, --set in all its forms, and the
scene it used written back (docs/own-fmu.md)."""

from __future__ import annotations

import json
import re
import tomllib
import zipfile

import pytest

from clockwork.errors import SceneError
from clockwork.run.catalog import load_scene
from clockwork.scene.fmu_alone import experiment_times
from cwtest import assert_one_line_error, fmu_file, run_cli, test_fmu


def _series(out):
    lines = (out / "timeseries.csv").read_text().splitlines()
    return lines[0].split(","), [row.split(",") for row in lines[1:]]


def test_an_fmu_runs_alone_with_its_default_experiment(capsys, tmp_path):
    fmu = test_fmu("TestDecay")  # DefaultExperiment: stop 1, step 0.1, tolerance 1e-3
    rc, out, err = run_cli(capsys, ["run", fmu, "--out", tmp_path / "r", "--no-progress"])
    assert rc == 0, err
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert summary["fmus"] == {"TestDecay": {"file": str(fmu), "sha256": summary["fmus"]["TestDecay"]["sha256"],
                                             "model": "TestDecay"}}
    assert summary["settings"]["experiment"] == {"start": 0.0, "stop": 1.0}
    assert summary["settings"]["master"]["step"] == 0.1 and summary["settings"]["master"]["tolerance"] is None
    assert summary["files"] == ["timeseries.csv", "outputs.png", "summary.json"]
    assert summary["columns"] == {"TestDecay.x": {"unit": None, "type": "Real", "variability": "continuous"}}
    header, rows = _series(tmp_path / "r")
    assert header == ["time", "TestDecay.x"] and len(rows) == 11 and rows[-1][0] == "1.0"
    assert "TestDecay: 1 run" in out


def test_an_fmu_run_alone_loads_no_ssp_writer_or_osp_reader_and_hashes_no_source(tmp_path):
    """A single run of an FMU (the first thing a user waits for) keeps to
    what it uses: no SSP writer, no OSP reader, and no digest of the
    package's source, which only a sweep's content-addressed points need."""
    import subprocess
    import sys

    code = ("import sys\n"
            "import clockwork.hashing as h\n"
            "def refused():\n    raise AssertionError('source_digest called')\n"
            "h.source_digest = refused\n"
            "import clockwork.run.points as p\n"
            "p.source_digest = refused\n"
            "from clockwork.cli import main\n"
            f"rc = main(['run', {str(test_fmu('TestDecay'))!r}, '--out', {str(tmp_path / 'r')!r}, '--no-plot', "
            "'--no-progress'])\n"
            "print(rc, *sorted(m for m in ('clockwork.scene.ssp.export', 'clockwork.scene.osp.read') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split()[-1:] == ["0"]


def test_validate_and_info_of_an_fmu(capsys):
    fmu = test_fmu("TestDecay")
    rc, out, err = run_cli(capsys, ["validate", fmu])
    assert rc == 0 and out.strip() == "ok: TestDecay (1 component, 0 connections)", err
    rc, out, err = run_cli(capsys, ["info", fmu])
    assert rc == 0, err
    assert ("clockwork run TestDecay.fmu: instance TestDecay, start 0 s, stop 1 s, step 0.1 s, tolerance 0.001"
            in out)


@pytest.mark.parametrize("setting", ["k=2", "TestDecay.k=2", "k=2.0"])
def test_set_takes_the_instance_prefix_or_not(capsys, tmp_path, setting):
    base = tmp_path / "base"
    rc, _, err = run_cli(capsys, ["run", test_fmu("TestDecay"), "--out", base, "--no-progress"])
    assert rc == 0, err
    rc, _, err = run_cli(capsys, ["run", test_fmu("TestDecay"), "--out", tmp_path / "set", "--no-progress",
                                  "--set", setting])
    assert rc == 0, err
    (_, a), (_, b) = _series(base), _series(tmp_path / "set")
    assert a[0] == b[0] and a[-1] != b[-1]  # the same start, a faster decay
    assert float(b[-1][1]) < float(a[-1][1])


def test_set_experiment_and_master(capsys, tmp_path):
    rc, _, err = run_cli(capsys, ["run", test_fmu("TestDecay"), "--out", tmp_path / "r", "--no-progress",
                                  "--set", "experiment.stop=2", "--set", "master.step=0.05"])
    assert rc == 0, err
    header, rows = _series(tmp_path / "r")
    assert len(rows) == 41 and rows[-1][0] == "2.0"
    summary = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert summary["settings"]["master"]["max_step"] == 0.05  # follows the step, as in a scene


@pytest.mark.parametrize("setting, needle", [
    ("kk=2", "has no variable kk (did you mean k?)"),
    ("x=2", 'TestDecay.x is an output (initial="calculated": the FMU computes its value); expected a parameter, '
            'an unconnected input or a variable with initial="exact" or "approx"'),
    ("k=fast", "expected"),
    ("experiment.stop=-1", "experiment.stop"),
    ("master.step=0", "master.step"),
    ("Other.k=2", "no component named Other; components: TestDecay"),
])
def test_a_bad_set_on_an_fmu_is_one_line(capsys, tmp_path, setting, needle):
    rc, _, err = run_cli(capsys, ["validate", test_fmu("TestDecay"), "--set", setting])
    assert_one_line_error(rc, err, "TestDecay.fmu", needle, code=2)


def test_a_dotted_variable_of_an_fmu_alone_needs_no_prefix_and_a_typo_is_named(capsys, tmp_path):
    fmu = _edited(test_fmu("TestDecay"), tmp_path / "dotted.fmu", 'name="k"', 'name="decay.k"')
    assert load_scene(fmu, ["decay.k=2"]).components["TestDecay"].parameters == {"decay.k": 2.0}
    assert load_scene(fmu, ["TestDecay.decay.k=3"]).components["TestDecay"].parameters == {"decay.k": 3.0}
    rc, _, err = run_cli(capsys, ["validate", fmu, "--set", "TestDecy.k=2"])
    assert_one_line_error(rc, err, "--set TestDecy.k", "no component named TestDecy (did you mean TestDecay?)")


def test_a_scene_of_one_component_takes_sets_without_the_prefix(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text('[scene]\ntitle = "t"\n[components.p]\nfmu = "Pendulum"\n[experiment]\nstop = 1\n')
    assert load_scene(f, ["Q=500"]).components["p"].parameters["Q"] == 500.0
    assert load_scene(f, ["p.Q=400"]).components["p"].parameters["Q"] == 400.0


def test_fmpy_defaults_where_the_default_experiment_is_silent(tmp_path):
    """No stepSize: fmpy's auto_interval of the span; no stopTime: start + 1; no startTime: 0."""
    from fmpy.util import auto_interval

    src = test_fmu("TestDecay")
    for attrs, expected in [('startTime="0" stopTime="3"', ({"start": 0.0, "stop": 3.0}, float(auto_interval(3.0)))),
                            ('startTime="2"', ({"start": 2.0, "stop": 3.0}, float(auto_interval(1.0)))),
                            ("", ({"start": 0.0, "stop": 1.0}, float(auto_interval(1.0))))]:
        fmu = _with_experiment(src, tmp_path / "e.fmu", f"<DefaultExperiment {attrs}/>" if attrs else "")
        import fmpy

        md = fmpy.read_model_description(str(fmu))
        assert experiment_times(md, fmu) == expected, attrs
    scene = load_scene(_with_experiment(src, tmp_path / "s.fmu", '<DefaultExperiment stopTime="3"/>'))
    assert scene.master.step == float(auto_interval(3.0)) == 0.005


def test_a_bad_default_experiment_is_one_line(capsys, tmp_path):
    fmu = _with_experiment(test_fmu("TestDecay"), tmp_path / "bad.fmu", '<DefaultExperiment stopTime="soon"/>')
    rc, _, err = run_cli(capsys, ["validate", fmu])
    assert_one_line_error(rc, err, "bad.fmu", "DefaultExperiment stopTime", "soon", code=2)


def _with_experiment(src, dst, element: str):
    """A copy of the FMU `src` whose modelDescription.xml has `element` as its DefaultExperiment."""
    import re

    return _edited(src, dst, re.compile(r"<DefaultExperiment[^>]*/>"), "", element)


def _edited(src, dst, old, new: str, experiment: str | None = None):
    """A copy of the FMU `src` with `old` (text or a pattern) replaced in its
    modelDescription.xml (and `experiment` put before its ModelVariables)."""
    with zipfile.ZipFile(src) as z:
        files = {i.filename: z.read(i.filename) for i in z.infolist()}
    xml = files["modelDescription.xml"].decode()
    xml = old.sub(new, xml) if hasattr(old, "sub") else xml.replace(old, new, 1)
    if experiment is not None:  # where FMI 2.0 wants it: before the (clockwork) VendorAnnotations
        anchor = "<VendorAnnotations>" if "<VendorAnnotations>" in xml else "<ModelVariables>"
        xml = xml.replace(anchor, experiment + anchor, 1)
    files["modelDescription.xml"] = xml.encode()
    with zipfile.ZipFile(dst, "w") as z:
        for name, data in files.items():
            z.writestr(name, data)
    return dst


def test_export_scene_round_trip_gives_the_same_bits(capsys, tmp_path):
    fmu = test_fmu("TestDecay")
    sets = ["--set", "k=3", "--set", "experiment.stop=2", "--set", "master.step=0.05"]
    rc, out, err = run_cli(capsys, ["export-scene", fmu, "--out", tmp_path / "decay.toml", *sets])
    assert rc == 0 and "wrote" in out, err
    text = (tmp_path / "decay.toml").read_text()
    raw = tomllib.loads(text)
    assert raw["components"]["TestDecay"]["parameters"] == {"k": 3.0}
    assert raw["experiment"] == {"start": 0.0, "stop": 2.0} and raw["master"]["step"] == 0.05
    assert raw["record"]["outputs"] == ["TestDecay.x"] and raw["plot"] == [{"kind": "outputs", "file": "outputs.png"}]
    rc, _, err = run_cli(capsys, ["run", fmu, "--out", tmp_path / "a", "--no-progress", *sets])
    assert rc == 0, err
    rc, _, err = run_cli(capsys, ["run", tmp_path / "decay.toml", "--out", tmp_path / "b", "--no-progress"])
    assert rc == 0, err
    assert (tmp_path / "a" / "timeseries.csv").read_bytes() == (tmp_path / "b" / "timeseries.csv").read_bytes()


def test_export_scene_writes_a_path_the_scene_finds(capsys, tmp_path):
    """An FMU outside the scene's folder is named by its absolute path; the scene loads from anywhere."""
    rc, _, err = run_cli(capsys, ["export-scene", fmu_file("Pendulum"), "--out", tmp_path / "p.toml"])
    assert rc == 0, err
    scene = load_scene(tmp_path / "p.toml")
    assert scene.components["Pendulum"].fmu_path == fmu_file("Pendulum").resolve()
    assert len(scene.record.outputs) > 3


@pytest.mark.parametrize("args, needle", [
    (["--out", "x.txt"], "expected a file name ending .toml"),
    (["--out", "no/such/dir/x.toml"], "no such directory"),
])
def test_export_scene_refuses_bad_output_paths(capsys, tmp_path, monkeypatch, args, needle):
    monkeypatch.chdir(tmp_path)
    rc, _, err = run_cli(capsys, ["export-scene", test_fmu("TestDecay"), *args])
    assert_one_line_error(rc, err, needle, code=2)


def test_export_scene_wants_an_fmu(capsys, tmp_path):
    f = tmp_path / "s.toml"
    f.write_text('[scene]\ntitle = "t"\n[components.p]\nfmu = "Pendulum"\n[experiment]\nstop = 1\n')
    rc, _, err = run_cli(capsys, ["export-scene", f, "--out", tmp_path / "o.toml"])
    assert_one_line_error(rc, err, "expected an FMU file", code=2)


@pytest.mark.parametrize("kind, needle", [("missing", "no such FMU file"), ("dir", "is a directory"),
                                          ("text", "not a zip archive")])
def test_a_bad_fmu_file_is_one_line(capsys, tmp_path, kind, needle):
    f = tmp_path / f"{kind}.fmu"
    if kind == "dir":
        f.mkdir()
    elif kind == "text":
        f.write_text("hello")
    rc, _, err = run_cli(capsys, ["run", f, "--out", tmp_path / "r"])
    assert_one_line_error(rc, err, needle, code=2)
    assert not (tmp_path / "r").exists()


def test_an_fmu_named_otherwise_is_pointed_to_its_suffix(capsys, tmp_path):
    f = tmp_path / "model.bin"
    f.write_bytes(test_fmu("TestDecay").read_bytes())
    with pytest.raises(SceneError, match="an FMU named X.fmu"):
        load_scene(f)


# --- start values the FMI standard lets a master set before initialization ----------------------------
# TestDecay with its parameter x0 (the start of x) declared as something else:
# an output with initial="exact" (FMI 2.0, 3.0), a local with initial="approx",
# an FMI 1.0 output with a start value (fixed, or a guess). The binary takes
# the value before initialization either way, so x starts at it.

def _redeclared(tmp_path, version: int, attrs: str, start: str = "") -> "Path":
    src = {1: test_fmu("fmi1/TestDecay"), 2: test_fmu("TestDecay"), 3: test_fmu("fmi3/TestDecay")}[version]
    out = tmp_path / f"Redeclared{version}.fmu"
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(out, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                xml = data.decode()
                if version == 3:
                    old = 'name="x0" valueReference="1" description="Initial value" causality="parameter" ' \
                          'variability="fixed" start="1"'
                    assert old in xml
                    xml = xml.replace(old, f'name="x0" valueReference="1" {attrs}{start}')
                    if 'causality="output"' in attrs:
                        xml = xml.replace('<Output valueReference="20"', '<Output valueReference="1"/><Output '
                                                                         'valueReference="20"')
                elif version == 2:
                    old = ('name="x0" valueReference="1" description="Initial value" causality="parameter" '
                           'variability="fixed">\n      <Real start="1"/>')
                    assert old in xml
                    xml = xml.replace(old, f'name="x0" valueReference="1" {attrs}>\n      <Real{start}/>')
                    if 'causality="output"' in attrs:
                        xml = xml.replace('<Outputs>', '<Outputs>\n      <Unknown index="2" dependencies=""/>')
                else:
                    old = ('name="x0" valueReference="1" description="Initial value" variability="parameter" '
                           'causality="internal">\n      <Real start="1" fixed="true"/>')
                    assert old in xml
                    xml = xml.replace(old, f'name="x0" valueReference="1" {attrs}>\n      <Real{start}/>')
                data = xml.encode()
            zout.writestr(item, data)
    return out


SETTABLE_BEFORE_INIT = {
    "FMI 2.0 output initial=exact": (2, 'causality="output" variability="continuous" initial="exact"', ' start="1"'),
    "FMI 2.0 local initial=approx": (2, 'causality="local" variability="continuous" initial="approx"', ' start="1"'),
    "FMI 2.0 tunable local initial=exact": (2, 'causality="local" variability="tunable" initial="exact"', ' start="1"'),
    "FMI 3.0 output initial=exact": (3, 'causality="output" variability="continuous" initial="exact"', ' start="1"'),
    "FMI 1.0 output with a fixed start": (1, 'variability="continuous" causality="output"', ' start="1" fixed="true"'),
    "FMI 1.0 output with a start (fixed by default)": (1, 'variability="continuous" causality="output"', ' start="1"'),
    "FMI 1.0 internal with a guess": (1, 'variability="continuous" causality="internal"', ' start="1" fixed="false"'),
}


def _x_column(out) -> list[str]:
    header, rows = _series(out)
    return [row[header.index("TestDecay.x")] for row in rows]


@pytest.mark.parametrize("engine", ["python", "compiled"])
@pytest.mark.parametrize("case", list(SETTABLE_BEFORE_INIT))
def test_a_start_value_the_standard_lets_a_master_set_is_set(capsys, tmp_path, case, engine):
    version, attrs, start = SETTABLE_BEFORE_INIT[case]
    fmu = _redeclared(tmp_path, version, attrs, start)
    ref = {1: test_fmu("fmi1/TestDecay"), 2: test_fmu("TestDecay"), 3: test_fmu("fmi3/TestDecay")}[version]
    common = ["--no-progress", "--set", f"master.engine={engine}", "--set", "record.outputs=['TestDecay.x']",
              "--set", "master.step=0.1", "--set", "experiment.stop=1"]
    rc, _, err = run_cli(capsys, ["run", ref, "--out", tmp_path / "ref", "--set", "x0=2", *common])
    assert rc == 0, err
    expected = _x_column(tmp_path / "ref")
    assert expected[0] == "2.0"
    # --set on the FMU alone, a scene file's parameters, an SSD's parameter binding: all set it
    rc, out, err = run_cli(capsys, ["validate", fmu, "--set", "x0=2"])
    assert rc == 0, err
    rc, _, err = run_cli(capsys, ["run", fmu, "--out", tmp_path / "alone", "--set", "x0=2", *common])
    assert rc == 0, err
    assert _x_column(tmp_path / "alone") == expected
    scene = tmp_path / "scene.toml"
    scene.write_text(f'[scene]\ntitle = "t"\n[components.TestDecay]\nfmu = "{fmu}"\nparameters = {{ x0 = 2 }}\n'
                     '[experiment]\nstop = 1\n[master]\nstep = 0.1\n')
    rc, _, err = run_cli(capsys, ["run", scene, "--out", tmp_path / "scene", *common])
    assert rc == 0, err
    assert _x_column(tmp_path / "scene") == expected
    ssd = tmp_path / "SystemStructure.ssd"
    ssd.write_text(f'''<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="1.0" name="one"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">
  <ssd:System name="root"><ssd:Elements>
    <ssd:Component name="TestDecay" source="{fmu.name}"><ssd:ParameterBindings><ssd:ParameterBinding>
      <ssd:ParameterValues><ssv:ParameterSet version="1.0" name="p"><ssv:Parameters>
        <ssv:Parameter name="x0"><ssv:Real value="2"/></ssv:Parameter>
      </ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues>
    </ssd:ParameterBinding></ssd:ParameterBindings></ssd:Component>
  </ssd:Elements></ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="1"/>
</ssd:SystemStructureDescription>
''')
    rc, _, err = run_cli(capsys, ["run", ssd, "--out", tmp_path / "ssd", *common])
    assert rc == 0, err
    assert _x_column(tmp_path / "ssd") == expected


NOT_SETTABLE_BEFORE_INIT = {
    "FMI 2.0 output initial=calculated": (2, "x=2", ['TestDecay.x is an output (initial="calculated"']),
    "FMI 2.0 constant": (2, "x0=2", ['is a local (variability="constant"']),
    "FMI 3.0 output initial=calculated": (3, "x=2", ['TestDecay.x is an output (initial="calculated"']),
    "FMI 3.0 independent variable": (3, "time=2", ["TestDecay.time is an independent (the independent variable"]),
    "FMI 1.0 output without a start": (1, "x=2", ['TestDecay.x is an output (initial="calculated"']),
}


@pytest.mark.parametrize("case", list(NOT_SETTABLE_BEFORE_INIT))
def test_a_value_the_standard_does_not_let_a_master_set_is_refused(capsys, tmp_path, case):
    version, setting, needles = NOT_SETTABLE_BEFORE_INIT[case]
    if case == "FMI 2.0 constant":
        fmu = _redeclared(tmp_path, 2, 'causality="local" variability="constant" initial="exact"', ' start="1"')
    else:
        fmu = {1: test_fmu("fmi1/TestDecay"), 2: test_fmu("TestDecay"), 3: test_fmu("fmi3/TestDecay")}[version]
    for cmd in (["validate", fmu], ["run", fmu, "--out", tmp_path / "out", "--no-progress"]):
        rc, _, err = run_cli(capsys, [*cmd, "--set", setting])
        assert_one_line_error(rc, err, str(fmu), f"--set TestDecay.{setting.split('=')[0]}", *needles,
                              'expected a parameter, an unconnected input or a variable with initial="exact"')
    assert not (tmp_path / "out").exists()


# --- DefaultExperiment values that validate passed and the run misused ------------------------------

def _experiment_edited(tmp_path, src, attrs: str) -> "Path":
    """`src` with its DefaultExperiment replaced by one of `attrs`."""
    out = tmp_path / "Edited.fmu"
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(out, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                xml = re.sub(r"<DefaultExperiment[^>]*/>", "", data.decode())
                xml = re.sub(r"(<(CoSimulation|ModelExchange)\b)", f"<DefaultExperiment {attrs}/>\\1", xml, count=1)
                data = xml.encode()
            zout.writestr(item, data)
    return out


# (attributes, words of the one line, a --set that gives the run a usable value instead)
BAD_EXPERIMENTS = {
    "tolerance 0": ('stopTime="1" stepSize="0.1" tolerance="0"', ["DefaultExperiment tolerance = 0",
                                                                  "relative tolerance > 0"], "master.tolerance=1e-3"),
    "tolerance -1": ('stopTime="1" stepSize="0.1" tolerance="-1"', ["DefaultExperiment tolerance = -1",
                                                                    "give master.tolerance"], "master.tolerance=1e-3"),
    "stepSize 1e-300": ('stopTime="1" stepSize="1e-300"', ["DefaultExperiment stepSize",
                                                           "expected a step >= master.min_step"], "master.step=0.1"),
    "stepSize 0": ('stopTime="1" stepSize="0"', ["DefaultExperiment stepSize = 0", "a time > 0"], "master.step=0.1"),
    "stepSize -0.1": ('stopTime="1" stepSize="-0.1"', ["DefaultExperiment stepSize = -0.1", "a time > 0"],
                      "master.step=0.1"),
    "stopTime before startTime": ('startTime="2" stopTime="1" stepSize="0.1"',
                                  ["DefaultExperiment stopTime = 1", "a time > experiment.start (2 s)"],
                                  "experiment.stop=3"),
    "stopTime INF": ('stopTime="INF" stepSize="0.1"', ["DefaultExperiment stopTime = inf", "expected a time"],
                     "experiment.stop=1"),
    "startTime -INF": ('startTime="-INF" stopTime="1" stepSize="0.1"',
                       ["DefaultExperiment startTime = -inf", "expected a time"], "experiment.start=0"),
    "stepSize NaN": ('stopTime="1" stepSize="NaN"', ["DefaultExperiment stepSize = nan", "expected a time"],
                     "master.step=0.1"),
    "tolerance NaN": ('stopTime="1" stepSize="0.1" tolerance="NaN"', ["DefaultExperiment tolerance = NaN",
                                                                       "a finite relative tolerance > 0"],
                      "master.tolerance=1e-3"),
    "tolerance INF": ('stopTime="1" stepSize="0.1" tolerance="INF"', ["DefaultExperiment tolerance = INF"],
                      "master.tolerance=1e-3"),
    "a stopTime past the recording bound": ('stopTime="1e12" stepSize="0.1"',
                                           ["DefaultExperiment stopTime: time_series over 1e+12 s", "steps"],
                                           "experiment.stop=1"),
    "a startTime with no stopTime past a double's resolution": (
        'startTime="1e17" stepSize="0.1"', ["DefaultExperiment startTime (no stopTime: the run stops 1 s after it)"],
        ("experiment.start=0", "experiment.stop=1")),
}


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("case", list(BAD_EXPERIMENTS))
def test_a_default_experiment_value_the_run_cannot_use_is_refused_by_name(capsys, tmp_path, case, version):
    attrs, needles, fix = BAD_EXPERIMENTS[case]
    fmu = _experiment_edited(tmp_path, test_fmu("TestDecay" if version == 2 else "fmi3/TestDecay"), attrs)
    for cmd in (["validate", fmu], ["run", fmu, "--out", tmp_path / "out", "--no-progress"]):
        rc, _, err = run_cli(capsys, cmd)
        assert_one_line_error(rc, err, f"{fmu}: modelDescription.xml: ", *needles)
    assert not (tmp_path / "out").exists()
    fixes = (fix,) if isinstance(fix, str) else fix
    rc, _, err = run_cli(capsys, ["run", fmu, "--out", tmp_path / "out", "--no-progress",
                                  *[a for f in fixes for a in ("--set", f)]])
    assert rc == 0, err


@pytest.mark.parametrize("engine", ["python", "compiled"])
@pytest.mark.parametrize("fmu", ["TestDecay", "MeOscillator"])
def test_a_non_positive_default_tolerance_is_refused_where_a_scene_would_use_it(capsys, tmp_path, fmu, engine):
    """A scene without master.tolerance gives each FMU its DefaultExperiment's: a Model Exchange
    FMU integrated at rtol -1 before; now refused naming the FMU's attribute, and master.tolerance
    runs it."""
    edited = _experiment_edited(tmp_path, test_fmu(fmu), 'stopTime="1" tolerance="-1"')
    scene = tmp_path / "scene.toml"
    scene.write_text(f'[scene]\ntitle = "t"\n[components.m]\nfmu = "{edited}"\n[experiment]\nstop = 0.5\n'
                     f'[master]\nstep = 0.1\nengine = "{engine}"\n')
    for cmd in (["validate", scene], ["run", scene, "--out", tmp_path / "out", "--no-progress"]):
        rc, _, err = run_cli(capsys, cmd)
        assert_one_line_error(rc, err, f"{edited}: modelDescription.xml: DefaultExperiment tolerance = -1",
                              "relative tolerance > 0", "master.tolerance")
    rc, _, err = run_cli(capsys, ["run", scene, "--out", tmp_path / "out", "--no-progress",
                                  "--set", "master.tolerance=1e-6"])
    assert rc == 0, err


def test_an_fmu_whose_default_experiment_says_inf_runs_in_a_scene_that_does_not_use_it(capsys, tmp_path):
    """INF and NaN are xs:doubles: the FMU is legal, and a scene that sets what it uses runs it
    (before: refused by the description check, whatever the scene said)."""
    edited = _experiment_edited(tmp_path, test_fmu("TestDecay"), 'startTime="-INF" stopTime="INF" stepSize="NaN"')
    scene = tmp_path / "scene.toml"
    scene.write_text(f'[scene]\ntitle = "t"\n[components.m]\nfmu = "{edited}"\n[experiment]\nstop = 0.5\n'
                     '[master]\nstep = 0.1\n')
    for cmd in (["validate", scene], ["run", scene, "--out", tmp_path / "out", "--no-progress"], ["info", edited]):
        rc, _, err = run_cli(capsys, cmd)
        assert rc == 0, err


# --- values that Python cannot turn into numbers, named by their key ---------------------------------

@pytest.mark.parametrize("setting, needles", [
    ("k=" + "9" * 100_000, ["--set k: an integer of more than 4300 digits"]),
    ("master.step=" + "9" * 5000, ["--set master.step: an integer of more than 4300 digits"]),
    ("master.tolerance=1" + "0" * 400, ["--set master.tolerance = 1000", "a relative tolerance > 0"]),
    ("master.iteration_tolerance=1" + "0" * 400, ["--set master.iteration_tolerance = 1000", "a number > 0"]),
    ("master.iterations=1" + "0" * 400, ["--set master.iterations = 1000", "an integer in [0, 2147483647]"]),
    ("k=1" + "0" * 400, ["--set TestDecay.k = 1000", "expected a finite number"]),
])
def test_a_number_python_cannot_hold_is_refused_under_its_key(capsys, tmp_path, setting, needles):
    for cmd in (["validate", test_fmu("TestDecay")],
                ["run", test_fmu("TestDecay"), "--out", tmp_path / "out", "--no-progress"]):
        rc, _, err = run_cli(capsys, [*cmd, "--set", setting])
        assert_one_line_error(rc, err, str(test_fmu("TestDecay")), *needles)
        assert len(err) < 1000
    assert not (tmp_path / "out").exists()


def test_a_scene_file_with_an_integer_of_5000_digits_is_one_line(capsys, tmp_path):
    scene = tmp_path / "scene.toml"
    scene.write_text(f'[scene]\ntitle = "t"\n[components.m]\nfmu = "{test_fmu("TestDecay")}"\n'
                     f'parameters = {{ k = {"9" * 5000} }}\n[experiment]\nstop = 1\n')
    rc, _, err = run_cli(capsys, ["validate", scene])
    assert_one_line_error(rc, err, str(scene), "malformed TOML: an integer of more than 4300 digits")


def test_validate_refuses_the_integrator_the_run_would_refuse(monkeypatch):
    """The Model Exchange wrapper chooses its integrator when the run starts: where CVode is asked
    for and cannot be had, validate says so too, under master.me_solver (before: only the run)."""
    from clockwork.engine import cvode
    monkeypatch.setattr(cvode, "problem", lambda: "no SUNDIALS here (the test says so)")
    fmu = test_fmu("MeOscillator")
    with pytest.raises(SceneError) as e:
        load_scene(fmu, ["master.me_solver=cvode"])
    assert e.value.key == "--set master.me_solver" and "no SUNDIALS here" in e.value.detail
    load_scene(fmu, ["master.me_solver=dp54"])  # the Runge-Kutta pairs need nothing


# --- the default recorded columns are fmpy's --------------------------------------------------------

def _no_outputs(tmp_path, src, version: int, states: bool = False):
    """`src` with its outputs made locals (and their ModelStructure entries dropped)."""
    out = tmp_path / f"NoOutputs{version}.fmu"
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(out, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                xml = data.decode()
                if version == 1:
                    xml = xml.replace('causality="output"', 'causality="internal"')
                    xml = re.sub(r"<DirectDependency\s*/>|<DirectDependency>.*?</DirectDependency>", "", xml,
                                 flags=re.S)
                else:
                    xml = xml.replace('causality="output"', 'causality="local"')
                    xml = re.sub(r"<Outputs>.*?</Outputs>", "", xml, flags=re.S)
                    xml = re.sub(r"<Output [^>]*/>", "", xml)
                data = xml.encode()
            zout.writestr(item, data)
    return out


def _fmpy_fields(fmu) -> list[str]:
    import fmpy
    return list(fmpy.simulate_fmu(str(fmu), stop_time=0.2, output_interval=0.1).dtype.names)


@pytest.mark.parametrize("fmu, version", [("TestDecay", 2), ("fmi3/TestDecay", 3), ("fmi1/TestDecay", 1),
                                          ("MeOscillator", 2), ("fmi3/MeOscillator", 3), ("TestTypes", 2)])
def test_the_default_columns_of_an_fmu_without_outputs_are_fmpys(capsys, tmp_path, fmu, version):
    """fmpy records, where an FMU has no output, its first five continuous states, else its first
    five variables (its rule for locals compares the variability with "local", which never holds):
    parameters and inputs too, numbers and Booleans (before: clockwork took up to five locals)."""
    import clockwork
    edited = _no_outputs(tmp_path, test_fmu(fmu), version)
    want = _fmpy_fields(edited)
    got = list(clockwork.simulate(str(edited), stop_time=0.2, output_interval=0.1).dtype.names)
    assert got == want
    assert len(want) > 1


@pytest.mark.parametrize("fmu", ["TestTypes", "fmi3/TestStair", "TestStair"])
def test_the_default_columns_of_an_fmu_with_outputs_are_fmpys_in_fmpys_order(fmu):
    """Every output, grouped by type as fmpy's Recorder orders them (Real, Integer and Enumeration,
    Boolean); a String output is recorded by clockwork only (fmpy drops it: docs/fmpy-migration.md)."""
    import clockwork
    got = list(clockwork.simulate(str(test_fmu(fmu)), stop_time=0.2, output_interval=0.1).dtype.names)
    md = load_scene(test_fmu(fmu)).components
    (comp,) = md.values()
    strings = [v.name for v in comp.model_description.modelVariables if v.causality == "output" and
               v.type in ("String", "Binary")]
    assert [n for n in got if n not in strings] == _fmpy_fields(test_fmu(fmu))


def test_an_fmu_alones_own_fault_is_named_as_the_fmu_not_connections(capsys, tmp_path):
    """An FMI 3.0 Model Exchange FMU with arrays (which the wrapper does not serve), run alone: the
    line names the FMU, not `connections` (it has none)."""
    from fmi3_linear import MODEL_DESCRIPTION
    fmu = test_fmu("fmi3/Linear")
    me = tmp_path / "LinearME.fmu"
    with zipfile.ZipFile(fmu) as zin, zipfile.ZipFile(me, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                xml = re.sub(r"<CoSimulation [^>]*/>", '<ModelExchange modelIdentifier="Linear"/>', data.decode())
                assert xml != MODEL_DESCRIPTION
                data = xml.encode()
            zout.writestr(item, data)
    for cmd in (["validate", me], ["run", me, "--out", tmp_path / "out", "--no-progress"]):
        rc, _, err = run_cli(capsys, cmd)
        assert_one_line_error(rc, err, f"{me}: Model Exchange with FMI 3.0 array variables is not supported")
        assert "connections" not in err


def test_an_fmu_alone_that_does_not_load_is_named_once_without_a_scene_key(capsys, tmp_path):
    """The binary refuses the description's GUID: validate's load check names the FMU, once,
    and no `components.<instance>.fmu` (an FMU alone has no scene file to hold that key)."""
    fmu = tmp_path / "OtherGuid.fmu"
    with zipfile.ZipFile(test_fmu("TestDecay")) as zin, zipfile.ZipFile(fmu, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                data = re.sub(rb'guid="[^"]*"', b'guid="{00000000-0000-0000-0000-000000000000}"', data, count=1)
            zout.writestr(item, data)
    for cmd in (["validate", fmu], ["run", fmu, "--out", tmp_path / "out", "--no-progress"]):
        rc, _, err = run_cli(capsys, cmd)
        assert_one_line_error(rc, err, f"{fmu}: fmi2Instantiate refused the model description's GUID")
        assert "components." not in err and err.count(str(fmu)) == 1, err


def test_a_value_an_fmu_alone_refuses_is_named_by_its_set_not_a_scene_key(capsys, tmp_path):
    """TestDecay declared with x initial="exact" (its binary refuses to set x): the FMU's refusal at the
    start is bad input named by the --set that gave it, not `components.TestDecay.parameters`."""
    fmu = tmp_path / "ExactX.fmu"
    with zipfile.ZipFile(test_fmu("TestDecay")) as zin, zipfile.ZipFile(fmu, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                old = b'causality="output" variability="continuous" initial="calculated">\n      <Real />'
                assert old in data
                data = data.replace(old, b'causality="output" variability="continuous" initial="exact">\n'
                                         b'      <Real start="1"/>')
            zout.writestr(item, data)
    for cmd in (["validate", fmu], ["run", fmu, "--out", tmp_path / "out", "--no-progress"]):
        rc, _, err = run_cli(capsys, [*cmd, "--set", "x=2"])
        assert_one_line_error(rc, err, f"{fmu}: the values --set gave TestDecay: ", "setting parameters (x = 2.0)")
        assert "components." not in err
    # in a scene file, the component's parameters; validate refuses it as run does (before: ok)
    scene = tmp_path / "scene.toml"
    scene.write_text(f'[scene]\ntitle = "t"\n[components.d]\nfmu = "{fmu}"\nparameters = {{ x = 2 }}\n'
                     '[experiment]\nstop = 1\n')
    for cmd in (["validate", scene], ["run", scene, "--out", tmp_path / "out", "--no-progress"]):
        rc, _, err = run_cli(capsys, cmd)
        assert_one_line_error(rc, err, f"{scene}: components.d.parameters: ", "setting parameters (x = 2.0)")


@pytest.mark.parametrize("case", ["FMI 2.0 output initial=exact", "FMI 1.0 output with a fixed start"])
def test_a_sweep_may_sweep_a_start_value_the_standard_lets_a_master_set(capsys, tmp_path, case):
    version, attrs, start = SETTABLE_BEFORE_INIT[case]
    fmu = _redeclared(tmp_path, version, attrs, start)
    scene = tmp_path / "sweep.toml"
    scene.write_text(f'[scene]\ntitle = "t"\n[components.TestDecay]\nfmu = "{fmu}"\n[experiment]\nstop = 0.5\n'
                     '[master]\nstep = 0.1\n[sweep]\naxes = [{ parameter = "TestDecay.x0", values = [2, 3] }]\n')
    rc, out, err = run_cli(capsys, ["validate", scene])
    assert rc == 0 and "2 sweep points" in out, err
    calculated = scene.read_text().replace("TestDecay.x0", "TestDecay.x")
    scene.write_text(calculated)
    rc, _, err = run_cli(capsys, ["validate", scene])
    assert_one_line_error(rc, err, "sweep.axes[0].parameter", 'TestDecay.x is an output, not a parameter',
                          'initial="calculated"')
