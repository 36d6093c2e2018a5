"""OSP import: `clockwork run | validate | info | export-scene` on libcosim's
OspSystemStructure.xml, and clockwork.simulate on it.

The fixtures (tests/data/osp/) are the core grasshopper clock written as OSP
system structures: `clock` (a LinearTransformation function doubling the
escapement's torque, a VariableConnection given input end first) and `bond`
(one VariableGroupConnection of nested groups from two
*_OspModelDescription.xml files, one beside the FMU and one beside the
file; stepSizes of two base steps). Each must give the bits of the same
system as an SSP (tests/data/ssp/flat10) or a TOML scene. `sums` (a Sum
and a VectorSum between three pendulums) and `rates` give libcosim's
numbers; `sumloop` puts a Sum in an algebraic loop.
"""

import re
import shutil
import textwrap
from pathlib import Path

import numpy as np
import pytest

from cwtest import BUILD_DIR, ROOT, assert_one_line_error, fmu_file, run_cli

import clockwork
from clockwork.errors import SceneError
from clockwork.run.catalog import load_scene

DATA = ROOT / "tests" / "data" / "osp"
FMUS = ("Pendulum", "GrasshopperEscapement")
SHORT = ["--set", "experiment.stop=5", "--set", "record.interval=0.01"]
NS = "http://opensimulationplatform.com/MSMI/OSPSystemStructure"


def fixture_dir(tmp_path: Path, name: str) -> Path:
    """A fixture's folder with the clock's FMUs copied into resources/."""
    d = tmp_path / name
    shutil.copytree(DATA / name, d)
    (d / "resources").mkdir(exist_ok=True)
    for f in FMUS:
        shutil.copy(fmu_file(f), d / "resources" / f"{f}.fmu")
    return d


def series(d: Path) -> dict[str, np.ndarray]:
    lines = (d / "timeseries.csv").read_text().splitlines()
    names = lines[0].split(",")
    data = np.array([[float(x) for x in line.split(",")] for line in lines[1:]])
    return {n: data[:, i] for i, n in enumerate(names)}


def run_ok(capsys, *argv) -> str:
    rc, out, err = run_cli(capsys, ["run", *argv, "--no-progress"])
    assert rc == 0, err
    return err


# ---------------------------------------------------------------- the fixtures


def test_clock_reads_as_the_ssp_does(tmp_path):
    d = fixture_dir(tmp_path, "clock")
    s = load_scene(d / "OspSystemStructure.xml")
    assert s.title == "clock"
    assert list(s.components) == ["pendulum", "escapement"]
    assert s.components["escapement"].parameters == {"torque": 0.004, "phi_r": 0.03490658503988659}
    assert s.components["pendulum"].parameters["Q"] == 1000.0
    links = {str(c): (c.factor, c.offset) for c in s.connections}
    # the VariableConnection names escapement.w first: the output end is the pendulum's
    assert links == {"pendulum.phi -> escapement.phi": (1.0, 0.0), "pendulum.w -> escapement.w": (1.0, 0.0),
                     "escapement.tau -> pendulum.tau_escapement": (2.0, 0.0)}
    assert (s.experiment.start, s.experiment.stop, s.master.step) == (0.0, 20.0, 0.01)


@pytest.mark.parametrize("engine", ["python", "compiled"])
def test_clock_gives_the_bits_of_the_ssp_and_the_scene(tmp_path, capsys, engine):
    """The LinearTransformation function is the SSP's linear transformation:
    the same bits as flat10 (an SSP) and core_grasshopper at 0.8 N.cm."""
    d = fixture_dir(tmp_path, "clock")
    ssp = tmp_path / "flat10"
    shutil.copytree(ROOT / "tests" / "data" / "ssp" / "flat10", ssp)
    for f in FMUS:
        shutil.copy(fmu_file(f), ssp / "resources" / f"{f}.fmu")
    eng = ["--set", f'master.engine="{engine}"']
    run_ok(capsys, d / "OspSystemStructure.xml", "--out", tmp_path / "osp", *SHORT, *eng)
    run_ok(capsys, ssp / "SystemStructure.ssd", "--out", tmp_path / "ssp", *SHORT, *eng)
    run_ok(capsys, "core_grasshopper", "--out", tmp_path / "toml", *SHORT, *eng, "--set",
           'escapement.torque="0.8 N.cm"', "--set", 'record.outputs=["pendulum.phi", "pendulum.w"]')
    a, b, c = (series(tmp_path / x) for x in ("osp", "ssp", "toml"))
    assert len(a["time"]) == 501
    for var in ("pendulum.phi", "pendulum.w"):
        assert np.array_equal(a[var], b[var])
        assert np.array_equal(a[var], c[var])
    assert a["pendulum.phi"].std() > 0.05  # it swings


def test_bond_connects_the_groups_pair_by_pair(tmp_path, capsys):
    """Nested groups pair up in order; each pair's output end comes from the
    FMUs; stepSizes of 2 (and 2.5, rounded down as libcosim does) base
    steps are the master's step: the bits of core_grasshopper."""
    d = fixture_dir(tmp_path, "bond")
    s = load_scene(d / "OspSystemStructure.xml")
    assert {str(c) for c in s.connections} == {
        "pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w", "escapement.tau -> pendulum.tau_escapement"}
    assert s.master.step == 0.01 and s.experiment.stop == 1.0
    err = run_ok(capsys, d / "OspSystemStructure.xml", "--out", tmp_path / "osp", *SHORT)
    assert "every 2 base steps (0.01 s), not every 0.0125 s" in err
    run_ok(capsys, "core_grasshopper", "--out", tmp_path / "toml", *SHORT,
           "--set", 'record.outputs=["pendulum.phi", "pendulum.w"]')
    a, b = series(tmp_path / "osp"), series(tmp_path / "toml")
    assert len(a["time"]) == 501
    for var in ("pendulum.phi", "pendulum.w"):
        assert np.array_equal(a[var], b[var])


def _types_osp(d: Path) -> Path:
    fmu = BUILD_DIR / "test-fmus" / "TestTypes.fmu"
    if not fmu.is_file():
        pytest.fail(f"{fmu} is missing: build the test FMUs first (cmake --build build)")
    d.mkdir(exist_ok=True)
    shutil.copy(fmu, d / "TestTypes.fmu")
    f = d / "OspSystemStructure.xml"
    f.write_text(textwrap.dedent(f"""\
        <OspSystemStructure xmlns="{NS}" version="0.1">
          <StartTime>0</StartTime><EndTime>0.1</EndTime><BaseStepSize>0.01</BaseStepSize>
          <Algorithm>FIXEDSTEP</Algorithm>
          <Simulators>
            <Simulator name="a" source="TestTypes.fmu">
              <InitialValues>
                <InitialValue variable="p_real"><Real value="1.5"/></InitialValue>
                <InitialValue variable="p_int"><Integer value="5"/></InitialValue>
                <InitialValue variable="p_bool"><Boolean value="1"/></InitialValue>
                <InitialValue variable="p_enum"><Integer value="3"/></InitialValue>
                <InitialValue variable="p_str"><String value="tock"/></InitialValue>
              </InitialValues>
            </Simulator>
            <Simulator name="b" source="file:TestTypes.fmu"/>
          </Simulators>
          <Functions><LinearTransformation name="lt" factor="2" offset="0.5"/></Functions>
          <Connections>
            <SignalConnection><Variable simulator="a" name="y_real"/><Signal function="lt" name="in"/></SignalConnection>
            <SignalConnection><Signal function="lt" name="out"/><Variable simulator="b" name="u_real"/></SignalConnection>
            <VariableConnection><Variable simulator="a" name="y_int"/><Variable simulator="b" name="u_int"/></VariableConnection>
            <VariableConnection><Variable simulator="b" name="u_bool"/><Variable simulator="a" name="y_bool"/></VariableConnection>
            <VariableConnection><Variable simulator="a" name="y_enum"/><Variable simulator="b" name="u_enum"/></VariableConnection>
            <VariableConnection><Variable simulator="a" name="y_real"/><Variable simulator="b" name="u_mm"/></VariableConnection>
          </Connections>
        </OspSystemStructure>
        """))
    return f


def test_every_type_of_initial_value_and_link(tmp_path, capsys):
    """Initial values of every OSP type, Integer, Boolean and Enumeration
    links, a linear transformation with an offset, and m into mm passed
    unconverted as libcosim passes it (with a warning)."""
    f = _types_osp(tmp_path / "types")
    s = load_scene(f)
    assert s.components["a"].parameters == {"p_real": 1.5, "p_int": 5, "p_bool": True, "p_enum": 3, "p_str": "tock"}
    record = 'record.outputs=["a.y_real", "b.y_mm", "b.y_real", "b.y_int", "b.y_bool", "b.y_enum"]'
    for engine in ("python", "auto"):
        err = run_ok(capsys, f, "--out", tmp_path / engine, "--set", record, "--set", f'master.engine="{engine}"')
        assert "a.y_real is in m, b.u_mm in mm: the value passes unconverted" in err
        last = {k: v[-1] for k, v in series(tmp_path / engine).items()}
        assert last["b.y_mm"] == 1.5  # unconverted
        assert last["b.y_real"] == 1 + 2 * 1.5 + 0.5
        assert last["b.y_int"] == 2 + 5
        assert last["b.y_bool"] == 1.0  # false xor true
        assert last["b.y_enum"] == 3.0


def test_export_ssp_keeps_the_links_as_the_osp_file_gives_them(tmp_path):
    """An OSP link passes m into mm unconverted: the SSP written of it says
    so (suppressUnitConversion), and reads back to the same links."""
    from clockwork.scene.ssp import export_ssp

    osp = load_scene(_types_osp(tmp_path / "types"))
    export_ssp(osp, tmp_path / "types.ssp")
    back = load_scene(tmp_path / "types.ssp")
    assert {str(c): (c.factor, c.offset) for c in back.connections} == \
           {str(c): (c.factor, c.offset) for c in osp.connections}
    assert next(c for c in back.connections if c.dst_var == "u_mm")[4:6] == (1.0, 0.0)


def test_validate_info_and_simulate(tmp_path, capsys):
    d = fixture_dir(tmp_path, "clock")
    f = d / "OspSystemStructure.xml"
    rc, out, err = run_cli(capsys, ["validate", f])
    assert rc == 0 and out.startswith("ok: clock (2 components, 3 connections)"), (out, err)
    rc, out, err = run_cli(capsys, ["info", f])
    assert rc == 0, err
    assert out.startswith("clock (OSP: 2 components, 3 connections)")
    assert "escapement.tau -> pendulum.tau_escapement (x 2)" in out
    # the folder, as libcosim takes it
    rc, out2, err = run_cli(capsys, ["info", d])
    assert rc == 0 and out2 == out, err
    assert load_scene(d).path == f
    r = clockwork.simulate(f, stop_time=1.0, output=["pendulum.phi"])
    run_ok(capsys, f, "--out", tmp_path / "cli", "--set", "experiment.stop=1", "--set", 'record.outputs=["pendulum.phi"]')
    assert np.array_equal(r["pendulum.phi"], series(tmp_path / "cli")["pendulum.phi"])


def test_export_scene_writes_a_scene_that_runs_the_same(tmp_path, capsys):
    d = fixture_dir(tmp_path, "bond")
    out = tmp_path / "bond.toml"
    rc, text, err = run_cli(capsys, ["export-scene", d / "OspSystemStructure.xml", "--out", out])
    assert rc == 0, err
    assert "2 components, 3 connections" in text
    a, b = load_scene(d / "OspSystemStructure.xml"), load_scene(out)
    assert a.connections == b.connections and a.master == b.master and a.experiment == b.experiment
    assert {n: c.parameters for n, c in a.components.items()} == {n: c.parameters for n, c in b.components.items()}
    capsys.readouterr()
    # a linear transformation has no form in a scene file: one line, nothing written
    d2 = fixture_dir(tmp_path, "clock")
    rc, _, err = run_cli(capsys, ["export-scene", d2 / "OspSystemStructure.xml", "--out", tmp_path / "c.toml"])
    assert_one_line_error(rc, err, "OspSystemStructure.xml", "escapement.tau -> pendulum.tau_escapement",
                          "x 2 + 0", "a scene file cannot say")
    assert not (tmp_path / "c.toml").exists()


def test_a_local_proxyfmu_runs_here(tmp_path, capsys):
    """proxyfmu://localhost?file=<path> (libcosim's FMU in a process of its
    own) is the same FMU, run in clockwork's process, with a note."""
    d = fixture_dir(tmp_path, "clock")
    f = d / "OspSystemStructure.xml"
    f.write_text(f.read_text().replace("resources/Pendulum.fmu", "proxyfmu://localhost?file=resources/Pendulum.fmu"))
    s = load_scene(f)
    assert s.components["pendulum"].fmu_path == d / "resources" / "Pendulum.fmu"
    assert "runs in clockwork's process" in capsys.readouterr().err


def test_set_overrides_initial_values_and_the_step(tmp_path, capsys):
    d = fixture_dir(tmp_path, "bond")
    s = load_scene(d / "OspSystemStructure.xml", ["pendulum.Q=321", "master.step=0.02"])
    assert s.components["pendulum"].parameters["Q"] == 321.0
    assert s.master.step == 0.02
    assert "--set master.step steps every component alike" in capsys.readouterr().err


def test_other_xml_files_name_the_format_expected(tmp_path, capsys):
    for name, text, needle in [
            ("s.xml", '<ssd:SystemStructureDescription xmlns:ssd="x"/>', "SSP system structure description"),
            ("modelDescription.xml", "<fmiModelDescription/>", "FMU's modelDescription.xml"),
            ("x.xml", "<a><b/></a>", "an XML file of root element a"),
            ("m_OspModelDescription.xml", "<OspModelDescription/>", "OSP model description")]:
        (tmp_path / name).write_text(text)
        rc, _, err = run_cli(capsys, ["validate", tmp_path / name])
        assert_one_line_error(rc, err, name, needle, "not a scene: expected", "OspSystemStructure.xml")
    # not a regular file, or no file: named, nothing read
    import os
    os.mkfifo(tmp_path / "fifo.xml")
    rc, _, err = run_cli(capsys, ["validate", tmp_path / "fifo.xml"])
    assert_one_line_error(rc, err, "fifo.xml", "is a FIFO (named pipe), expected an OspSystemStructure.xml file")
    rc, _, err = run_cli(capsys, ["validate", tmp_path / "gone.xml"])
    assert_one_line_error(rc, err, "gone.xml", "no such OSP system structure")
    # an OSP system structure named otherwise: named, not a TOML error
    (tmp_path / "osp.toml").write_text(f'<OspSystemStructure xmlns="{NS}" version="0.1"/>')
    rc, _, err = run_cli(capsys, ["validate", tmp_path / "osp.toml"])
    assert_one_line_error(rc, err, "osp.toml", "Open Simulation Platform system structure (name it .xml)")


# Files of other kinds given where a scene goes: (name, bytes or None for a directory, what the line says)
NOT_SCENES = [
    ("other.xml", b"<root/>", "an XML file of root element root, not a scene"),
    ("binary.xml", bytes(range(256)), "malformed XML at line 1: Document is empty; expected an "
                                      "OspSystemStructure.xml file"),
    ("text.xml", b"a = 1\n", "malformed XML at line 1: Start tag expected, '<' not found; expected an "
                             "OspSystemStructure.xml file"),
    ("empty.xml", b"", "malformed XML at line 1: Document is empty; expected an OspSystemStructure.xml file"),
    ("notzip.ssp", b"hello", "expected an SSP archive"),
    ("notzip.fmu", b"hello", "is not an FMU: not a zip archive"),
    ("empty.fmu", b"", "is not an FMU: not a zip archive"),
    ("adir", None, "is a directory without an OspSystemStructure.xml, not a scene"),
    ("binary.bin", bytes(range(128, 256)), "not UTF-8 text (byte 0), so not a scene"),
    ("binary", b"\x1f\x8b\x08\x00\xff", "not UTF-8 text (byte 1), so not a scene"),
    ("a.json", b'{"scene": {"title": "x"}}', "a JSON file, not a scene"),
    ("empty.json", b"", "a .json file that is no scene (no [scene] table)"),
    ("settings.ini", b"a = 1\n", "a .ini file that is no scene (no [scene] table)"),
    ("data.csv", b"time,x\n0,1\n", "a .csv file that is no TOML, not a scene"),
]


@pytest.mark.parametrize("command", ["validate", "run"])
@pytest.mark.parametrize("name,data,needle", NOT_SCENES, ids=[c[0] for c in NOT_SCENES])
def test_files_of_other_kinds_name_the_format_expected(tmp_path, capsys, command, name, data, needle):
    f = tmp_path / name
    if data is None:
        f.mkdir()
    else:
        f.write_bytes(data)
    argv = [command, f] + (["--out", tmp_path / "out"] if command == "run" else [])
    rc, _, err = run_cli(capsys, argv)
    assert_one_line_error(rc, err, name, needle)
    assert "TOML:" not in err and "malformed TOML" not in err
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------- hostile files


def _clock_text() -> str:
    return (DATA / "clock" / "OspSystemStructure.xml").read_text()


def _edit(old: str, new: str, fixture: str = "clock"):
    """A maker of the fixture's file with `old` replaced by `new` (once), in the folder it is given."""
    def make(d: Path) -> Path:
        text = (DATA / fixture / "OspSystemStructure.xml").read_text()
        assert old in text, old
        (d / "OspSystemStructure.xml").write_text(text.replace(old, new, 1))
        return d / "OspSystemStructure.xml"
    return make


def _write(text: str):
    def make(d: Path) -> Path:
        (d / "OspSystemStructure.xml").write_text(text)
        return d / "OspSystemStructure.xml"
    return make


def _huge(d: Path) -> Path:
    f = d / "OspSystemStructure.xml"
    text = _clock_text()
    f.write_text(text.replace("<Simulators>", "<!--" + "x" * (17 << 20) + "--><Simulators>"))
    return f


LAUGHS = ('<?xml version="1.0"?><!DOCTYPE lolz [<!ENTITY lol "lol"><!ENTITY lol2 "&lol;&lol;&lol;&lol;">]>'
          f'<OspSystemStructure xmlns="{NS}" version="0.1"><Simulators/>&lol2;</OspSystemStructure>')
XXE = ('<?xml version="1.0"?><!DOCTYPE x [<!ENTITY e SYSTEM "file:///etc/passwd">]>'
       f'<OspSystemStructure xmlns="{NS}" version="0.1"><StartTime>&e;</StartTime><Simulators/></OspSystemStructure>')
SIM = '<Simulator name="escapement" source="resources/GrasshopperEscapement.fmu">'

HOSTILE = {
    "malformed XML": (_edit("</Simulators>", "</Simulator>"), "malformed XML at line"),
    "entity expansion": (_write(LAUGHS), "DOCTYPE", "not allowed in OSP files"),
    "external entity": (_write(XXE), "DOCTYPE"),
    "empty file": (_write(""), "malformed XML"),
    "too big": (_huge, "bytes"),
    "wrong namespace": (_edit(NS, "urn:x"), "line 7: OspSystemStructure", "expected the namespace"),
    "no namespace": (_edit(f' xmlns="{NS}"', ""), "expected the namespace"),
    "wrong version": (_edit('version="0.1"', 'version="2.0"'), "version='2.0'", 'expected version="0.1"'),
    "unknown top element": (_edit("<Simulators>", "<Extra/><Simulators>"), "Extra", "not part of"),
    "two StartTimes": (_edit("<EndTime>", "<StartTime>1</StartTime><EndTime>"), "expected one StartTime"),
    "no simulators": (_write(f'<OspSystemStructure xmlns="{NS}" version="0.1"/>'), "expected a Simulators"),
    "empty simulators": (_write(f'<OspSystemStructure xmlns="{NS}" version="0.1"><Simulators/>'
                                '</OspSystemStructure>'), "Simulators", "at least one Simulator"),
    "bad time": (_edit("<EndTime>20<", "<EndTime>twenty<"), "EndTime", "expected a number"),
    "infinite time": (_edit("<EndTime>20<", "<EndTime>INF<"), "EndTime", "finite"),
    "end before start": (_edit("<EndTime>20<", "<EndTime>-1<"), "EndTime", "> experiment.start"),
    "zero base step": (_edit("<BaseStepSize>0.01<", "<BaseStepSize>0<"), "BaseStepSize", "step > 0"),
    "ecco": (_edit("<Algorithm>fixedStep<", "<Algorithm>ecco<"), "Algorithm", "ecco algorithm", "fixedStep"),
    "unknown algorithm": (_edit("<Algorithm>fixedStep<", "<Algorithm>rk4<"), "Algorithm", "'rk4'"),
    "missing FMU": (_edit("resources/Pendulum.fmu", "resources/Gone.fmu"), "Simulator 'pendulum'",
                    "Gone.fmu: no such file"),
    "FMU is a directory": (_edit("resources/Pendulum.fmu", "resources"), "Simulator 'pendulum'", "is a directory"),
    "remote FMU": (_edit("resources/Pendulum.fmu", "proxyfmu://server:9090?file=Pendulum.fmu"),
                   "proxyfmu:", "another machine"),
    "proxyfmu without a file": (_edit("resources/Pendulum.fmu", "proxyfmu://localhost?fil=Pendulum.fmu"),
                                "one file=<path>"),
    "unknown URI scheme": (_edit("resources/Pendulum.fmu", "http://x/Pendulum.fmu"), "http:", "not supported"),
    "other host": (_edit("resources/Pendulum.fmu", "file://server/Pendulum.fmu"), "another host"),
    "no source": (_edit(' source="resources/Pendulum.fmu"', ""), "Simulator 'pendulum' source",
                  "missing required attribute"),
    "duplicate simulator": (_edit(SIM, SIM.replace("escapement", "pendulum", 1)), "Simulator name='pendulum'",
                            "unique simulator name"),
    "bad simulator name": (_edit(SIM, SIM.replace('"escapement"', '"a b"', 1)), "simulator name"),
    "function named as a simulator": (_edit('name="double"', 'name="pendulum"'), "LinearTransformation",
                                      "unique name"),
    "unknown variable in a value": (_edit('variable="Q"', 'variable="Qx"'), "InitialValue variable='Qx'",
                                    "has no variable Qx"),
    "value of the wrong type": (_edit('<Real value="1000"/>', '<Integer value="1000"/>'), "type mismatch"),
    "bad real": (_edit('<Real value="1000"/>', '<Real value="lots"/>'), "Real value='lots'", "expected a number"),
    "bad boolean value": (_edit('<Real value="1000"/>', '<Real value="1000"/><Boolean value="yes"/>'),
                          "expected one value element"),
    "value out of range": (_edit('variable="Q"><Real value="1000"', 'variable="Q"><Real value="-5"'), "Q"),
    "value of an output": (_edit('variable="Q"', 'variable="energy"'), "energy", "is an output"),
    "two values": (_edit('<InitialValue variable="Q"><Real value="1000"/></InitialValue>',
                         '<InitialValue variable="Q"><Real value="1000"/></InitialValue>'
                         '<InitialValue variable="Q"><Real value="1"/></InitialValue>'), "each variable once"),
    "unknown simulator in a connection": (_edit('<Variable simulator="escapement" name="phi"/>',
                                                '<Variable simulator="escapment" name="phi"/>'),
                                          "simulator='escapment'", "no simulator named escapment"),
    "unknown variable in a connection": (_edit('<Variable simulator="escapement" name="phi"/>',
                                               '<Variable simulator="escapement" name="psi"/>'),
                                         "Variable", "has no variable psi"),
    "two outputs": (_edit('<Variable simulator="escapement" name="phi"/>',
                          '<Variable simulator="escapement" name="tau"/>'), "both outputs"),
    "two inputs": (_edit('<Variable simulator="pendulum" name="phi"/>',
                         '<Variable simulator="pendulum" name="g_factor"/>'), "expected an output at one end"),
    "input fed twice": (_edit('<Variable simulator="escapement" name="w"/>',
                              '<Variable simulator="escapement" name="phi"/>'), "line 39: VariableConnection",
                        "input escapement.phi is fed twice: line 35 feeds it pendulum.phi"),
    "one variable": (_edit('<Variable simulator="pendulum" name="w"/>', ""), "expected two Variable"),
    "unknown connection": (_edit("</Connections>", "<Link/></Connections>"), "Link", "expected VariableConnection"),
    "signal of no function": (_edit('<Signal function="double" name="in"/>', '<Signal function="half" name="in"/>'),
                              "no function named half"),
    "unconnected function": (_edit('<Signal function="double" name="out"/>', '<Signal function="double" name="in"/>'),
                             "expected one connection to double:in"),
    "function without its out": (_edit('<Functions>', '<Functions><LinearTransformation name="t2"/>'),
                                 "LinearTransformation 't2'", "t2:in"),
    "bad signal name": (_edit('<Signal function="double" name="out"/>', '<Signal function="double" name="y"/>'),
                        "expected in or out"),
    "bad factor": (_edit('factor="2"', 'factor="two"'), "factor='two'", "expected a number"),
    "unconnected sum": (_edit('<Functions>', '<Functions><Sum name="s" inputCount="2"/>'), "Sum 's'",
                        "expected a SignalConnection to s:in[0]"),
    "unconnected vector sum": (_edit('<Functions>', '<Functions><VectorSum name="s" inputCount="2" dimension="3"/>'),
                               "VectorSum 's'", "expected a SignalGroupConnection to s:in[0]"),
    "sum without inputCount": (_edit('<Functions>', '<Functions><Sum name="s"/>'), "Sum 's'", "inputCount"),
    "sum of no inputs": (_edit('<Functions>', '<Functions><Sum name="s" inputCount="0"/>'), "inputCount='0'",
                         "whole number from 1"),
    "unknown function": (_edit('<Functions>', '<Functions><Switch name="s"/>'), "Switch", "not an OSP function"),
    "empty signal group connection": (_edit("</Connections>", '<SignalGroupConnection/></Connections>'),
                                      "SignalGroupConnection", "expected one VariableGroup and one SignalGroup"),
    # steps that differ are the simulators' own (multi-rate): not with the escapement's event location
    "different steps": (_edit(SIM, SIM.replace(">", ' stepSize="0.02">')), "stepSize='0.02'",
                        "master.event_location",
                        "the event indicators of a slow component", "escapement every 2 base steps"),
    "zero stepSize": (_edit(SIM, SIM.replace(">", ' stepSize="0">')), "stepSize", "step > 0"),
    "group without a model description": (_edit("</Connections>", '<VariableGroupConnection>'
                                                '<VariableGroup simulator="pendulum" name="g"/>'
                                                '<VariableGroup simulator="escapement" name="g"/>'
                                                '</VariableGroupConnection></Connections>'),
                                          "VariableGroup", "Pendulum_OspModelDescription.xml"),
    "string in a link": (_edit('<Variable simulator="escapement" name="tau"/>',
                               '<Variable simulator="escapement" name="mode"/>'), "LinearTransformation takes"),
}


class TestHostileFiles:
    """Each bad file: one line naming the file and the element, exit 2, nothing written."""

    @pytest.mark.parametrize("case", list(HOSTILE))
    def test_one_line(self, tmp_path, capsys, case):
        make, *needles = HOSTILE[case]
        d = fixture_dir(tmp_path, "clock")
        f = make(d)
        rc, _, err = run_cli(capsys, ["run", f, "--out", tmp_path / "out", "--no-progress"])
        assert_one_line_error(rc, err, "OspSystemStructure.xml", *needles)
        assert not (tmp_path / "out").exists()

    @pytest.mark.parametrize("edit, needles", [
        (("<Generic name=\"swing\">", "<Generic name=\"swing\"><Variable ref=\"nope\"/>"),
         ("GrasshopperEscapement_OspModelDescription.xml: line 4: Variable ref='nope'", "has no variable nope")),
        (("<Variable ref=\"tau\"/>", ""), ("OspSystemStructure.xml", "VariableGroupConnection", "differ in size",
                                        "escapement's drive has 0 variables, pendulum's drive 1")),
        (("<Generic name=\"swing\">", "<Generic name=\"swing\"/><Generic name=\"swing\">"), ("unique group name",)),
        (("<VariableGroups>", "<!DOCTYPE x><VariableGroups>"), ("malformed XML",)),
    ])
    def test_bad_model_description(self, tmp_path, capsys, edit, needles):
        d = fixture_dir(tmp_path, "bond")
        md = d / "GrasshopperEscapement_OspModelDescription.xml"
        md.write_text(md.read_text().replace(*edit, 1))
        rc, _, err = run_cli(capsys, ["validate", d / "OspSystemStructure.xml"])
        assert_one_line_error(rc, err, *needles)

    def test_unknown_group(self, tmp_path, capsys):
        d = fixture_dir(tmp_path, "bond")
        f = d / "OspSystemStructure.xml"
        f.write_text(f.read_text().replace('simulator="pendulum" name="swing"', 'simulator="pendulum" name="sway"'))
        rc, _, err = run_cli(capsys, ["validate", f])
        assert_one_line_error(rc, err, "OspSystemStructure.xml", "VariableGroup", "no variable group sway",
                              "groups: swing")

    def test_nested_group_by_name(self, tmp_path):
        """A nested group may be named alone (libcosim searches below the top)."""
        d = fixture_dir(tmp_path, "bond")
        f = d / "OspSystemStructure.xml"
        f.write_text(f.read_text().replace('name="swing"', 'name="angle"'))
        s = load_scene(f)
        assert {str(c) for c in s.connections} == {"pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w"}

    def test_scene_error_is_raised_by_the_api(self, tmp_path):
        d = fixture_dir(tmp_path, "clock")
        _edit('variable="Q"', 'variable="Qx"')(d)
        with pytest.raises(SceneError, match="has no variable Qx"):
            load_scene(d / "OspSystemStructure.xml")


def test_random_edits_give_a_scene_or_one_line(tmp_path, capsys):
    """150 seeded edits of the fixtures' files (an attribute dropped, emptied
    or set to a bad value, an element's text changed, an element dropped,
    doubled or renamed): each loads, or fails with one SceneError line
    naming a file of the fixture; nothing else escapes."""
    import random

    from lxml import etree

    rng = random.Random(39)
    outcomes = {"loaded": 0, "refused": 0}
    bad = ["", "x", "-1", "0", "1e999", "nan", "..", "a.b", "true", "pendulum", "in", "out", "proxyfmu://h?file=x"]
    for i in range(150):
        d = fixture_dir(tmp_path / str(i), rng.choice(["clock", "bond"]))
        f = rng.choice(sorted(d.rglob("*.xml")))
        tree = etree.parse(str(f))
        el = rng.choice([e for e in tree.getroot().iter() if isinstance(e.tag, str)])
        op = rng.choice(["drop_attr", "set_attr", "text", "drop_el", "dup_el", "rename"])
        parent = el.getparent()
        if op in ("drop_attr", "set_attr") and el.attrib:
            key = rng.choice(sorted(el.attrib))
            if op == "drop_attr":
                del el.attrib[key]
            else:
                el.set(key, rng.choice(bad))
        elif op == "text" and not len(el):
            el.text = rng.choice(bad)
        elif op == "drop_el" and parent is not None:
            parent.remove(el)
        elif op == "dup_el" and parent is not None:
            parent.append(etree.fromstring(etree.tostring(el)))
        elif op == "rename":
            el.tag += "X"
        tree.write(str(f))
        try:
            load_scene(d / "OspSystemStructure.xml")
            outcomes["loaded"] += 1
        except SceneError as e:
            assert "\n" not in str(e) and str(d) in str(e), str(e)
            outcomes["refused"] += 1
    capsys.readouterr()  # the warnings of edits that load
    assert outcomes["refused"] > 50 and outcomes["loaded"] > 10, outcomes


# ---------------------------------------------------------------- several rates


def _rates_dir(tmp_path: Path) -> Path:
    d = tmp_path / "rates"
    shutil.copytree(DATA / "rates", d)
    (d / "resources").mkdir(exist_ok=True)
    for f in ("Pendulum", "MechanismVibration"):
        shutil.copy(fmu_file(f), d / "resources" / f"{f}.fmu")
    return d


RATES_OUTPUTS = ["pendulum.phi", "vibration.a2", "follower.phi"]


def _libcosim_rows(osp: Path, steps: int, outputs: list[str] = RATES_OUTPUTS) -> np.ndarray:
    """libcosim's fixed-step algorithm on the file: after each base step,
    the time and the last values its observer holds of `outputs` (a slow
    simulator's, those of its last finished step)."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.ERROR)
    ex = CosimExecution.from_osp_config_file(str(osp))
    obs = CosimObserver.create_last_value()
    ex.add_observer(obs)
    refs = []
    for name in outputs:
        inst, var = name.split(".")
        idx = ex.slave_index_from_instance_name(inst)
        vrs = {(v.name.decode() if isinstance(v.name, bytes) else v.name): v.reference
               for v in ex.slave_variables(idx)}
        refs.append((idx, vrs[var]))
    rows = []
    for _ in range(steps):
        assert ex.step()
        rows.append([ex.status().current_time * 1e-9] + [obs.last_real_values(i, [r])[0] for i, r in refs])
    return np.array(rows)


@pytest.mark.parametrize("engine", ["python", "compiled"])
def test_three_rates_give_libcosims_numbers(tmp_path, capsys, engine):
    """stepSizes of 1, 3 and 2 base steps (a link between the factors 3
    and 2 passes every 6 base steps), libcosim's algorithm (Jacobi, inputs
    held from each simulator's own step start): libcosim's numbers at every
    base step, for the fast simulator and the slow ones alike, on either
    engine, and the same bits on both. The times differ in the last bits
    (libcosim's are whole nanoseconds, clockwork's start + k * step; the
    single-rate system differs by as much), so the values agree to 1e-12
    rad; running every simulator at the base step instead moves them by
    more than 1e-4 rad."""
    pytest.importorskip("libcosimpy")
    d = _rates_dir(tmp_path)
    osp = d / "OspSystemStructure.xml"
    recorded = f"record.outputs={RATES_OUTPUTS!r}".replace("'", '"')
    err = run_ok(capsys, osp, "--out", tmp_path / "cw", "--set", 'master.order="jacobi"',
                 "--set", f'master.engine="{engine}"', "--set", recorded)
    assert "error" not in err
    if engine == "compiled":  # the Python engine's bits
        run_ok(capsys, osp, "--out", tmp_path / "py", "--set", 'master.order="jacobi"',
               "--set", 'master.engine="python"', "--set", recorded)
        assert (tmp_path / "cw" / "timeseries.csv").read_bytes() == (tmp_path / "py" / "timeseries.csv").read_bytes()
    ours = series(tmp_path / "cw")
    theirs = _libcosim_rows(osp, 300)
    assert len(ours["time"]) == 301
    assert np.allclose(ours["time"][1:], theirs[:, 0], rtol=0, atol=1e-12)
    for j, name in enumerate(RATES_OUTPUTS, start=1):
        assert np.max(np.abs(ours[name][1:] - theirs[:, j])) < 1e-12, name
    # the slow ones hold between their points (vibration every 3, follower every 2)
    a2 = ours["vibration.a2"]
    assert all(a2[n] == a2[n - n % 3] for n in range(1, 301))
    # and the rates matter: all at the base step is another system
    run_ok(capsys, osp, "--out", tmp_path / "one", "--set", 'master.order="jacobi"', "--set", "master.step=0.01",
           "--set", f"record.outputs={RATES_OUTPUTS!r}".replace("'", '"'))
    one = series(tmp_path / "one")
    assert np.max(np.abs(one["follower.phi"] - ours["follower.phi"])) > 1e-4


def test_three_rates_info_and_validate_show_each_step(tmp_path, capsys):
    d = _rates_dir(tmp_path)
    osp = d / "OspSystemStructure.xml"
    rc, out, err = run_cli(capsys, ["info", osp])
    assert rc == 0, err
    assert "step: 0.03 s (3 base steps of 0.01 s)" in out and "step: 0.02 s (2 base steps of 0.01 s)" in out
    rc, out, err = run_cli(capsys, ["validate", osp])
    assert rc == 0, err
    assert "steps: pendulum 0.01 s (1 base step of 0.01 s), vibration 0.03 s (3 base steps of 0.01 s), " \
           "follower 0.02 s (2 base steps of 0.01 s)" in out
    s = load_scene(osp)
    assert (s.components["vibration"].step, s.components["follower"].step) == (0.03, 0.02)
    assert s.components["pendulum"].step is None and s.master.step == 0.01


def test_an_end_time_off_the_base_grid_with_rates_names_the_file(tmp_path, capsys):
    d = _rates_dir(tmp_path)
    osp = d / "OspSystemStructure.xml"
    osp.write_text(osp.read_text().replace("<EndTime>3</EndTime>", "<EndTime>3.005</EndTime>"))
    rc, _, err = run_cli(capsys, ["validate", osp])
    assert_one_line_error(rc, err, str(osp), "EndTime", "whole number of base steps")


def test_three_rates_export_scene_keeps_the_steps(tmp_path, capsys):
    """export-scene writes each component's step: the TOML scene runs the
    OSP file's numbers, bit for bit."""
    d = _rates_dir(tmp_path)
    osp = d / "OspSystemStructure.xml"
    # a scene's links convert units only: the file without its linear transformation
    text = osp.read_text()
    text = text[:text.index("<Functions>")] + text[text.index("</Functions>") + len("</Functions>"):]
    text = text[:text.index("<SignalConnection>")] + text[text.rindex("</SignalConnection>") +
                                                          len("</SignalConnection>"):]
    osp.write_text(text)
    rc, _, err = run_cli(capsys, ["export-scene", osp, "--out", tmp_path / "rates.toml"])
    assert rc == 0, err
    text = (tmp_path / "rates.toml").read_text()
    assert "step = 0.03" in text and "step = 0.02" in text
    short = ["--set", "experiment.stop=0.6", "--set", f"record.outputs={RATES_OUTPUTS!r}".replace("'", '"')]
    run_ok(capsys, osp, "--out", tmp_path / "a", *short)
    run_ok(capsys, tmp_path / "rates.toml", "--out", tmp_path / "b", *short)
    assert (tmp_path / "a" / "timeseries.csv").read_bytes() == (tmp_path / "b" / "timeseries.csv").read_bytes()


# ---------------------------------------------------------------- Sum and VectorSum


def _sums_dir(tmp_path: Path) -> Path:
    d = tmp_path / "sums"
    shutil.copytree(DATA / "sums", d)
    (d / "resources").mkdir(exist_ok=True)
    shutil.copy(fmu_file("Pendulum"), d / "resources" / "Pendulum.fmu")
    return d


SUMS_OUTPUTS = ["a.phi", "b.phi", "c.phi", "c.w"]


def test_sums_read_as_libcosim_adds(tmp_path):
    """A Sum's inputs in[0], in[1], ... and a VectorSum's groups element by
    element: one link per term into the function's input, the first starting
    the sum and the others added in the order of their indices (libcosim's
    in[0] + in[1] + ...), whatever order the connections are written in."""
    s = load_scene(_sums_dir(tmp_path) / "OspSystemStructure.xml")
    terms = [(str(c), c.adds) for c in s.connections]
    assert terms == [("b.phi -> a.tau_external", False), ("c.phi -> a.tau_external", True),
                     ("c.w -> a.tau_external", True),
                     ("a.phi -> b.tau_external", False), ("c.phi -> b.tau_external", True),
                     ("a.w -> b.tau_coupling", False), ("c.w -> b.tau_coupling", True)]
    assert all((c.factor, c.offset) == (1.0, 0.0) for c in s.connections)


def test_sums_give_libcosims_numbers_on_both_engines(tmp_path, capsys):
    """libcosim's fixed-step algorithm passes the simulators' outputs into
    the functions after every step, sums them and passes the sums on at the
    same communication point; clockwork's Jacobi step with the sums as links
    gives libcosim's numbers (to the last bits of the times, as for the
    rates above), and the same bits on both engines."""
    pytest.importorskip("libcosimpy")
    d = _sums_dir(tmp_path)
    osp = d / "OspSystemStructure.xml"
    record = f"record.outputs={SUMS_OUTPUTS!r}".replace("'", '"')
    got = {}
    for engine in ("python", "compiled"):
        err = run_ok(capsys, osp, "--out", tmp_path / engine, "--set", 'master.order="jacobi"',
                     "--set", f'master.engine="{engine}"', "--set", record)
        assert "error" not in err
        got[engine] = series(tmp_path / engine)
    for name in SUMS_OUTPUTS:
        assert np.array_equal(got["python"][name], got["compiled"][name]), name
    ours = got["compiled"]
    theirs = _libcosim_rows(osp, 200, SUMS_OUTPUTS)
    assert len(ours["time"]) == 201
    assert np.allclose(ours["time"][1:], theirs[:, 0], rtol=0, atol=1e-12)
    for j, name in enumerate(SUMS_OUTPUTS, start=1):
        assert np.max(np.abs(ours[name][1:] - theirs[:, j])) < 1e-12, name
    # the further terms count: a Sum of in[0] alone swings a otherwise
    f = d / "OspSystemStructure.xml"
    text = re.sub(r'<SignalConnection>\s*<Variable simulator="c" name="(phi|w)"/>\s*'
                  r'<Signal function="mix" name="in\[[12]\]"/>\s*</SignalConnection>', "", f.read_text())
    f.write_text(text.replace('inputCount="3"', 'inputCount="1"'))
    run_ok(capsys, f, "--out", tmp_path / "one", "--set", 'master.order="jacobi"', "--set", record)
    assert np.max(np.abs(series(tmp_path / "one")["a.phi"] - ours["a.phi"])) > 1e-4


def test_sums_across_rates_give_libcosims_numbers(tmp_path, capsys):
    """A Sum whose terms come from simulators of other rates: each term
    passes as libcosim passes it (at the least common multiple of the
    source's and the target's decimation factors)."""
    pytest.importorskip("libcosimpy")
    d = _sums_dir(tmp_path)
    osp = d / "OspSystemStructure.xml"
    osp.write_text(osp.read_text().replace('<Simulator name="c" source="resources/Pendulum.fmu">',
                                           '<Simulator name="c" source="resources/Pendulum.fmu" stepSize="0.03">')
                   .replace('<Simulator name="b" source="resources/Pendulum.fmu">',
                            '<Simulator name="b" source="resources/Pendulum.fmu" stepSize="0.02">'))
    run_ok(capsys, osp, "--out", tmp_path / "cw", "--set", 'master.order="jacobi"',
           "--set", f"record.outputs={SUMS_OUTPUTS!r}".replace("'", '"'))
    ours = series(tmp_path / "cw")
    theirs = _libcosim_rows(osp, 200, SUMS_OUTPUTS)
    for j, name in enumerate(SUMS_OUTPUTS, start=1):
        assert np.max(np.abs(ours[name][1:] - theirs[:, j])) < 1e-12, name


def _sums_edit(old: str, new: str):
    return _edit(old, new, "sums")


BAD_SUMS = {
    "inputCount too small": (_sums_edit('inputCount="3"', 'inputCount="2"'), "Signal name='in[2]'",
                             "mix has no signal in[2]; expected in[0], in[1] or out"),
    "inputCount too large": (_sums_edit('inputCount="3"', 'inputCount="4"'), "Sum 'mix'",
                             "expected a SignalConnection to mix:in[3]"),
    "no such input": (_sums_edit('name="in[2]"', 'name="in[x]"'), "mix has no signal in[x]"),
    "input twice": (_sums_edit('name="in[2]"', 'name="in[1]"'), "expected one connection to mix:in[1]"),
    "signal connection to a vector sum": (_sums_edit(
        '<SignalConnection>\n            <Variable simulator="b" name="phi"/>\n            '
        '<Signal function="mix" name="in[0]"/>',
        '<SignalConnection>\n            <Variable simulator="b" name="phi"/>\n            '
        '<Signal function="pair" name="in[0]"/>'), "pair is a VectorSum: expected a SignalGroupConnection"),
    "dimension mismatch": (_sums_edit('dimension="2"', 'dimension="3"'), "SignalGroupConnection",
                           "dimension mismatch: pair adds vectors of dimension 3, a's variable group state has "
                           "2 variables"),
    "no such group": (_sums_edit('simulator="c" name="state"', 'simulator="c" name="speed"'),
                      "no top-level variable group speed"),
    "sum of an input": (_sums_edit('<Variable simulator="c" name="phi"/>', '<Variable simulator="c" name="tau_drag"/>'),
                        "expected an output at mix:in[1]: c.tau_drag is an input"),
    "sum into an output": (_sums_edit('<Variable simulator="a" name="tau_external"/>',
                                      '<Variable simulator="a" name="w"/>'),
                           "expected an input at mix:out: a.w is an output"),
    "summed input fed twice": (_sums_edit('</Connections>', '<VariableConnection><Variable simulator="c" name="phi"/>'
                                          '<Variable simulator="a" name="tau_external"/></VariableConnection>'
                                          '</Connections>'), "input a.tau_external is fed twice"),
}


@pytest.mark.parametrize("case", list(BAD_SUMS))
def test_bad_sums_give_one_line(tmp_path, capsys, case):
    make, *needles = BAD_SUMS[case]
    f = make(_sums_dir(tmp_path))
    rc, _, err = run_cli(capsys, ["run", f, "--out", tmp_path / "out", "--no-progress"])
    assert_one_line_error(rc, err, "OspSystemStructure.xml", *needles)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("setting, needles", [
    ("master.extrapolation=1", ("master.extrapolation = 1: not supported with a sum into", "an OSP Sum")),
    ("master.iterations=2", ("master.iterations = 2: not supported with a sum into",)),
])
def test_sums_refuse_what_goes_through_one_source(tmp_path, capsys, setting, needles):
    f = _sums_dir(tmp_path) / "OspSystemStructure.xml"
    rc, _, err = run_cli(capsys, ["run", f, "--out", tmp_path / "out", "--no-progress", "--set", setting])
    assert_one_line_error(rc, err, *needles)


def test_sums_are_not_exported_where_a_format_cannot_say_them(tmp_path, capsys):
    f = _sums_dir(tmp_path) / "OspSystemStructure.xml"
    rc, _, err = run_cli(capsys, ["export-scene", f, "--out", tmp_path / "s.toml"])
    assert_one_line_error(rc, err, "c.phi -> a.tau_external", "a sum of several outputs (an OSP Sum)")
    rc, _, err = run_cli(capsys, ["export-ssp", f, "--out", tmp_path / "s.ssp"])
    assert_one_line_error(rc, err, "an SSP feeds an input from one output", "not exported")
    assert not (tmp_path / "s.toml").exists() and not (tmp_path / "s.ssp").exists()




def test_a_sum_inside_an_algebraic_loop(tmp_path, capsys):
    """p.w = q.s + r.s and q.w = 0.5 p.s, with s = sum(x) + w (direct
    feedthrough): an algebraic loop through a Sum, one term from inside it
    and one from outside. Linear does not allow outputs to be read after
    inputs are set without a step, so the loop is solved in Initialization
    Mode (the solver takes every term: p.s = sum(p.x) + q.s + r.s there) and
    broken by a one-step delay in the steps (p.s = sum(p.x) + the sum of
    the step's start); the same bits on both engines."""
    from cwtest import test_fmu

    shutil.copytree(DATA / "sumloop", tmp_path, dirs_exist_ok=True)
    shutil.copy(test_fmu("fmi3/Linear"), tmp_path / "Linear.fmu")
    osp = tmp_path / "OspSystemStructure.xml"
    record = '["p.s", "q.s", "r.s", "p.x", "q.x"]'
    got = {}
    for engine in ("python", "compiled"):
        err = run_ok(capsys, osp, "--out", tmp_path / engine, "--set", f'master.engine="{engine}"',
                     "--set", f"record.outputs={record}")
        assert "solved in Initialization Mode, then broken by a one-step delay" in err
        got[engine] = series(tmp_path / engine)
    for name in got["python"]:
        assert np.array_equal(got["python"][name], got["compiled"][name]), name
    s = got["compiled"]
    px = s["p.x[0]"] + s["p.x[1]"] + s["p.x[2]"]
    qx = s["q.x[0]"] + s["q.x[1]"] + s["q.x[2]"]
    assert abs(s["p.s"][0] - (px[0] + s["q.s"][0] + s["r.s"][0])) < 1e-8
    assert abs(s["q.s"][0] - (qx[0] + 0.5 * s["p.s"][0])) < 1e-8
    assert np.max(np.abs(s["p.s"][1:] - (px[1:] + s["q.s"][:-1] + s["r.s"][:-1]))) < 1e-12
    assert np.min(np.abs(s["r.s"])) > 0.1  # the outside term counts


@pytest.mark.parametrize("links, needle", [
    ([("a", "phi", "b", "tau_external", 1.0, 0.0, True)], "no link before it starts"),
    ([("a", "phi", "b", "tau_external", 2.0, 0.0), ("a", "w", "b", "tau_external", 1.0, 0.0, True)],
     "no link before it starts as it is"),
    ([("a", "phi", "b", "tau_external"), ("a", "w", "b", "tau_external", 3.0, 0.0, True)], "a sum adds"),
])
def test_api_sums_need_a_plain_start(links, needle):
    """Through the Python API (Link.adds): a term added to nothing, to a
    transformed link or with a transformation of its own is refused."""
    from clockwork.engine.system import System

    path = str(fmu_file("Pendulum"))
    with pytest.raises(SceneError, match=needle):
        System({"a": (path, {}), "b": (path, {})}, links)
