"""Hostile input, as a table: every ordinary mistake a user can make with the
CLI, a scene file, an override, the result directory, the cache or an FMU's
state gets its exit code (2 bad input, 1 failed simulation, 0 a physical
result such as a stall) and one stderr line that names the file and the key.

Each case builds its input in a fresh directory and runs ``clockwork.cli.main``
in-process; an uncaught exception fails the case. docs/reliability.md counts
the rows of this table.
"""

from __future__ import annotations

import json
import os
import textwrap
import zipfile
from pathlib import Path

import pytest

from clockwork import cli
from cwtest import CLOCK_SCENE, FMU_DIR, fmu_file

TINY = textwrap.dedent("""\
    [scene]
    title = "tiny"

    [components.pendulum]
    fmu = "Pendulum"
    parameters = { L = "1 m", phi_start = "5 deg" }

    [experiment]
    stop = "0.2 s"

    [master]
    step = "0.01 s"

    [record]
    outputs = ["pendulum.phi"]

    [analysis]
    kind = "time_series"
    """)

SWEPT = TINY.replace('[analysis]', '[sweep]\naxes = [ { parameter = "pendulum.L", values = ["1 m", "2 m"] } ]\n\n'
                     '[analysis]')

CLOCK = CLOCK_SCENE.format(stop=2, sweep="")

CHRONOMETER = CLOCK.replace('fmu = "GrasshopperEscapement"', 'fmu = "ChronometerEscapement"').replace(
    'parameters = { torque = "0.4 N.cm", phi_r = "2 deg" }',
    'parameters = { torque = "0.4 N.cm", alpha_m1 = "-2 deg", alpha_m2 = "2 deg" }').replace(
    '"pendulum.phi -> escapement.phi",', '"pendulum.phi -> escapement.phi",')

DIVERGING = textwrap.dedent("""\
    connections = ["pendulum.phi -> vibration.a1", "vibration.tau -> pendulum.tau_coupling"]
    [scene]
    title = "past the stability limit"
    [components.pendulum]
    fmu = "Pendulum"
    parameters = { Q = 0, phi_start = "5 deg", rtol = 1e-11, atol = 1e-13 }
    [components.vibration]
    fmu = "MechanismVibration"
    parameters = { kappa = 0.0, C1 = 1.0, C2 = 5.0, a2_start = 1e-3, rtol = 1e-11, atol = 1e-13 }
    [experiment]
    stop = "1000 s"
    [master]
    step = "1.28 s"
    order = "jacobi"
    extrapolation = 2
    [record]
    outputs = ["pendulum.phi"]
    [analysis]
    kind = "time_series"
    """)


class Case:
    """One hostile input: how to build it, and what the user must see."""

    def __init__(self, name, build, code, *needles):
        self.name, self.build, self.code, self.needles = name, build, code, needles


def scene(text, name="scene.toml"):
    """A builder that writes `text` as a scene file and returns its path."""
    def write(d: Path) -> Path:
        f = d / name
        f.write_text(text) if isinstance(text, str) else f.write_bytes(text)
        return f
    return write


def run_scene(text, *extra, name="scene.toml"):
    return lambda d: ["run", scene(text, name)(d), "--out", d / "out", "--no-progress", *extra]


def validate(text, *extra, name="scene.toml"):
    return lambda d: ["validate", scene(text, name)(d), *extra]


def tiny_set(*overrides):
    return validate(TINY, *[a for o in overrides for a in ("--set", o)])


def with_fmu(data: bytes, name="X.fmu"):
    def build(d: Path):
        (d / name).write_bytes(data)
        return ["validate", scene(TINY.replace('fmu = "Pendulum"', f'fmu = "{name}"'))(d)]
    return build


def fmu_dir_named_fmu(d: Path):
    (d / "X.fmu").mkdir()
    return ["validate", scene(TINY.replace('fmu = "Pendulum"', 'fmu = "X.fmu"'))(d)]


def fmu_variant(edit_xml=None, drop=()):
    """Pendulum.fmu with its modelDescription edited or members left out."""
    def build(d: Path):
        src, dst = fmu_file("Pendulum"), d / "P.fmu"
        with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
            for item in zin.infolist():
                if any(item.filename.startswith(p) for p in drop):
                    continue
                data = zin.read(item)
                if item.filename == "modelDescription.xml" and edit_xml:
                    data = edit_xml(data)
                zout.writestr(item, data)
        return ["run", scene(TINY.replace('fmu = "Pendulum"', 'fmu = "P.fmu"'))(d), "--out", d / "out"]
    return build


def nested(depth):
    return "[scene]\ntitle = \"deep\"\n[x]\ny = " + "[" * depth + "]" * depth + "\n"


def with_file(name: str, data: bytes, case: str):
    """`compare` of a result file holding `data` against `case`."""
    def build(d: Path):
        (d / name).write_bytes(data)
        return ["compare", d / name, case]
    return build


def out_below_file(d: Path):
    (d / "afile").write_text("x")
    return ["run", scene(TINY)(d), "--out", d / "afile" / "below", "--no-progress"]


def out_is_file(d: Path):
    (d / "afile").write_text("x")
    return ["run", scene(TINY)(d), "--out", d / "afile", "--no-progress"]


def out_is_scene_dir(d: Path):
    return ["run", scene(TINY)(d), "--out", d, "--no-progress"]


def out_is_root(d: Path):
    return ["run", scene(TINY)(d), "--out", "/", "--no-progress"]


def scene_is_dir(d: Path):
    (d / "dir.toml").mkdir()
    return ["validate", d / "dir.toml"]


def scene_unreadable(d: Path):
    f = scene(TINY)(d)
    f.chmod(0)
    return ["validate", f]


def cache_is_file(d: Path):
    (d / "cachefile").write_text("x")
    os.environ["CLOCKWORK_CACHE"] = str(d / "cachefile")
    return ["run", scene(SWEPT)(d), "--out", d / "out", "--no-progress"]


def gallery_unknown(d: Path):
    return ["gallery", "--quick", "--only", "no_such_figure", "--out", d / "g"]


def export_ssp_below_file(d: Path):
    (d / "afile").write_text("x")
    return ["export-ssp", scene(CLOCK)(d), "--out", d / "afile" / "x.ssp"]


def export_ssp_bad_suffix(d: Path):
    return ["export-ssp", scene(CLOCK)(d), "--out", d / "x.zip"]


BIG = 10 ** 400

CASES = [
    # --- the command line
    Case("no command", lambda d: [], 2, "required"),
    Case("unknown command", lambda d: ["frobnicate"], 2, "invalid choice", "frobnicate"),
    Case("run without --out", lambda d: ["run", scene(TINY)(d)], 2, "--out"),
    Case("workers zero", lambda d: ["run", scene(TINY)(d), "--out", d / "o", "--workers", "0"], 2, "--workers"),
    Case("workers negative", lambda d: ["run", scene(TINY)(d), "--out", d / "o", "--workers", "-3"], 2, "--workers"),
    Case("workers text", lambda d: ["run", scene(TINY)(d), "--out", d / "o", "--workers", "many"], 2, "--workers"),
    Case("workers huge", lambda d: ["run", scene(TINY)(d), "--out", d / "o", "--workers", str(BIG)], 2, "--workers"),
    Case("info unknown model", lambda d: ["info", "NoSuchModel"], 2, "NoSuchModel"),
    Case("info relative path", lambda d: ["info", "no/such.fmu"], 2, "no/such.fmu", "current directory"),
    Case("list missing dir", lambda d: ["list", d / "nodir"], 2, "nodir", "no such directory"),
    Case("gallery unknown figure", gallery_unknown, 2, "no_such_figure"),
    Case("export-ssp below a file", export_ssp_below_file, 2, "afile"),
    Case("export-ssp not .ssp", export_ssp_bad_suffix, 2, "x.zip", ".ssp"),
    Case("compare missing result", lambda d: ["compare", d / "nope.csv", "GrasshopperClock"], 2, "nope.csv"),
    Case("compare without a time column", with_file("r.csv", b"a,b\n1,2\n3,4\n", "GrasshopperClock"), 2,
         "r.csv", "time"),
    Case("compare unknown case", with_file("r.csv", b"time,phi\n0,0\n1,1\n", "NoSuchCase"), 2, "NoSuchCase"),
    Case("compare binary result", with_file("r.csv", b"\xff\xfe\x00", "GrasshopperClock"), 2, "r.csv"),
    Case("export-suite below a file", lambda d: out_below_file(d) and ["export-suite", d / "afile" / "kit"], 2,
         "afile"),
    # --- the scene file
    Case("missing scene", lambda d: ["validate", d / "missing.toml"], 2, "missing.toml", "no such scene file"),
    Case("scene is a directory", scene_is_dir, 2, "dir.toml"),
    Case("scene is empty", validate(""), 2, "scene.toml"),
    Case("scene is an endless device", lambda d: ["validate", "/dev/zero"], 2, "/dev/zero", "character device"),
    Case("scene not UTF-8", validate(b"\xff\xfe[scene]\x00\x81"), 2, "scene.toml"),
    Case("an FMU named .toml", lambda d: ["validate", scene(fmu_file("Pendulum").read_bytes())(d)], 2, "scene.toml",
         "zip archive, not a scene", "an FMU named X.fmu"),
    Case("a zip archive named .toml", validate(b"PK\x03\x04\x14\x00\x00\x00\x08\x00\xff\xfe"), 2, "scene.toml",
         "zip archive, not a scene"),
    Case("scene malformed TOML", validate("[scene\ntitle = 1"), 2, "scene.toml", "TOML"),
    # another format given for a scene: named, with what was expected (not a TOML parse error)
    # an OSP system structure is read (tests/test_osp.py): this one's namespace is not libcosim's
    Case("an OSP system structure", validate('<?xml version="1.0"?>\n<OspSystemStructure xmlns="x"/>',
                                             name="OspSystemStructure.xml"), 2, "OspSystemStructure.xml",
         "line 2: OspSystemStructure", "expected the namespace http://opensimulationplatform.com/MSMI/"),
    Case("an SSD named .xml", validate('<ssd:SystemStructureDescription xmlns:ssd="x"/>', name="s.xml"), 2,
         "s.xml", "SSP system structure description named .xml (name it .ssd)"),
    Case("a modelDescription.xml", validate("<fmiModelDescription/>", name="modelDescription.xml"), 2,
         "FMU's modelDescription.xml"),
    Case("XML named .toml", validate("<a><b/></a>"), 2, "scene.toml", "XML file (root element a)"),
    Case("a JSON file", validate('{"scene": 1}', name="s.json"), 2, "s.json", "a JSON file, not a scene"),
    Case("a Markdown file", validate("# title\n\nsome text\n", name="README.md"), 2, "README.md",
         "a .md file that is no TOML, not a scene: expected"),
    Case("scene over 1 MiB", validate(TINY + "#" * (1 << 21) + "\n"), 2, "scene.toml", "at most 1048576 bytes"),
    Case("nesting 5000 deep", validate(nested(5000)), 2, "scene.toml"),
    Case("unknown top key", validate(TINY + "[mastr]\nstep = 1\n"), 2, "scene.toml", "mastr"),
    Case("unknown master key", validate(TINY.replace("[master]", "[master]\nstepp = 1")), 2, "scene.toml",
         "master.stepp"),
    Case("stop 400 digits", validate(TINY.replace('stop = "0.2 s"', f"stop = {BIG}")), 2, "scene.toml",
         "experiment.stop"),
    Case("stop negative", validate(TINY.replace('stop = "0.2 s"', "stop = -1")), 2, "scene.toml", "experiment.stop"),
    Case("stop not a number", validate(TINY.replace('stop = "0.2 s"', 'stop = "soon"')), 2, "scene.toml",
         "experiment.stop"),
    Case("stop infinite", validate(TINY.replace('stop = "0.2 s"', "stop = inf")), 2, "scene.toml",
         "experiment.stop"),
    Case("step zero", validate(TINY.replace('step = "0.01 s"', "step = 0")), 2, "scene.toml", "master.step"),
    Case("step nan", validate(TINY.replace('step = "0.01 s"', "step = nan")), 2, "scene.toml", "master.step"),
    Case("step below time resolution", validate(TINY.replace('step = "0.01 s"', "step = 1e-300")), 2,
         "scene.toml", "master.min_step", "1e-300 s"),
    Case("order unknown", validate(TINY.replace("[master]", '[master]\norder = "random"')), 2, "scene.toml",
         "master.order"),
    Case("extrapolation 7", validate(TINY.replace("[master]", "[master]\nextrapolation = 7")), 2, "scene.toml",
         "master.extrapolation"),
    Case("parameter out of range", validate(TINY.replace('L = "1 m"', "L = -1")), 2, "scene.toml",
         "components.pendulum.parameters.L"),
    Case("parameter wrong unit", validate(TINY.replace('L = "1 m"', 'L = "3 deg"')), 2, "scene.toml",
         "components.pendulum.parameters.L"),
    Case("parameter unknown", validate(TINY.replace('L = "1 m"', "Length = 1")), 2, "scene.toml",
         "components.pendulum.parameters.Length"),
    Case("parameter is an output", validate(TINY.replace('L = "1 m"', "phi = 1")), 2, "scene.toml",
         "components.pendulum.parameters.phi"),
    Case("parameter 400 digits", validate(TINY.replace('L = "1 m"', f"L = {BIG}")), 2, "scene.toml",
         "components.pendulum.parameters.L"),
    Case("parameter a table", validate(TINY.replace('L = "1 m"', "L = { a = 1 }")), 2, "scene.toml",
         "components.pendulum.parameters.L"),
    Case("component without fmu", validate(TINY.replace('fmu = "Pendulum"\n', "")), 2, "scene.toml",
         "components.pendulum"),
    Case("fmu unknown name", validate(TINY.replace('fmu = "Pendulum"', 'fmu = "Pendulm"')), 2, "scene.toml",
         "components.pendulum.fmu", "Pendulum"),
    Case("fmu garbage", with_fmu(b"\x00garbage\xff" * 10), 2, "scene.toml", "components.pendulum.fmu"),
    Case("fmu is a directory", fmu_dir_named_fmu, 2, "scene.toml", "components.pendulum.fmu", "is a directory"),
    Case("fmu zip without description", with_fmu(b"PK\x05\x06" + b"\x00" * 18), 2, "scene.toml",
         "components.pendulum.fmu"),
    Case("fmu without binary", fmu_variant(drop=("binaries/",)), 2, "scene.toml", "components.pendulum.fmu"),
    Case("fmu with broken XML", fmu_variant(edit_xml=lambda x: x[: len(x) // 2]), 2, "scene.toml",
         "components.pendulum.fmu"),
    Case("connection to unknown port", validate(TINY.replace("[scene]", 'connections = ["pendulum.phi -> '
                                                             'pendulum.nothing"]\n[scene]')),
         2, "scene.toml", "connections[0]", "no variable nothing"),
    Case("connection not a string", validate(TINY.replace("[scene]", "connections = [1]\n[scene]")), 2,
         "scene.toml", "connections"),
    Case("record unknown output", validate(TINY.replace('["pendulum.phi"]', '["pendulum.psi"]')), 2,
         "scene.toml", "record.outputs[0]", "no variable psi"),
    Case("record interval zero", validate(TINY.replace("[record]", "[record]\ninterval = 0")), 2,
         "scene.toml", "record.interval"),
    Case("analysis unknown kind", validate(TINY.replace('kind = "time_series"', 'kind = "fourier"')), 2,
         "scene.toml", "analysis.kind"),
    Case("sweep 1e12 points", validate(TINY.replace("[analysis]", '[sweep]\naxes = [ { parameter = "pendulum.L",'
                                                    ' start = 1, stop = 2, num = 1000000000000 } ]\n[analysis]')),
         2, "scene.toml", "sweep"),
    Case("sweep product over limit", validate(TINY.replace("[analysis]", '[sweep]\naxes = [ '
                                                           '{ parameter = "pendulum.L", start = 1, stop = 2, num = 2000 },'
                                                           '{ parameter = "pendulum.Q", start = 1, stop = 2, num = 2000 }'
                                                           ' ]\n[analysis]')),
         2, "scene.toml", "sweep"),
    Case("sweep num zero", validate(TINY.replace("[analysis]", '[sweep]\naxes = [ { parameter = "pendulum.L",'
                                                 ' start = 1, stop = 2, num = 0 } ]\n[analysis]')),
         2, "scene.toml", "sweep"),
    Case("sweep unknown parameter", validate(TINY.replace("[analysis]", '[sweep]\naxes = [ { parameter = '
                                                          '"pendulum.LL", values = [1, 2] } ]\n[analysis]')),
         2, "scene.toml", "sweep.axes[0].parameter", "no variable LL"),
    Case("sweep value out of range", validate(TINY.replace("[analysis]", '[sweep]\naxes = [ { parameter = '
                                                           '"pendulum.L", values = [1, -2] } ]\n[analysis]')),
         2, "scene.toml", "sweep.axes[0].values[1]", "expected a value in"),
    Case("plot overwrites sweep.csv", validate(TINY + '[[plot]]\nkind = "time_series"\nx = "time"\n'
                                               'y = ["pendulum.phi"]\nfile = "sweep.csv"\n'), 2, "scene.toml",
         "plot", "sweep.csv"),
    Case("plot overwrites summary.json", validate(TINY + '[[plot]]\nkind = "time_series"\nx = "time"\n'
                                                  'y = ["pendulum.phi"]\nfile = "summary.json"\n'), 2,
         "scene.toml", "summary.json"),
    Case("plot unknown y", validate(TINY + '[[plot]]\nkind = "time_series"\nx = "time"\ny = ["pendulum.psi"]\n'
                                    'file = "a.png"\n'), 2, "scene.toml", "pendulum.psi"),
    Case("plot file escapes the result dir", validate(TINY + '[[plot]]\nkind = "time_series"\nx = "time"\n'
                                                      'y = ["pendulum.phi"]\nfile = "../a.png"\n'), 2,
         "scene.toml", "plot"),
    # --- overrides
    Case("set without =", tiny_set("pendulum.L"), 2, "--set pendulum.L"),
    Case("set unknown component", tiny_set("pendlum.L=1"), 2, "--set pendlum.L"),
    Case("set unknown parameter", tiny_set("pendulum.phi_strt=1"), 2, "--set pendulum.phi_strt", "phi_start"),
    Case("set out of range", tiny_set("pendulum.phi_start=400 deg"), 2, "--set pendulum.phi_start"),
    Case("set wrong unit", tiny_set("pendulum.L=2 s"), 2, "--set pendulum.L"),
    Case("set 400 digits", tiny_set(f"experiment.stop={BIG}"), 2, "--set experiment.stop"),
    Case("set step nan", tiny_set("master.step=nan"), 2, "--set master.step"),
    Case("set stop inf", tiny_set("experiment.stop=inf"), 2, "--set experiment.stop"),
    Case("set deep nesting", tiny_set("x=" + "[" * 5000 + "]" * 5000), 2, "--set x"),
    Case("set unknown section", tiny_set("nowhere.key=1"), 2, "--set nowhere.key"),
    Case("set empty key", tiny_set("=1"), 2, "--set"),
    # --- the result directory
    Case("out empty", lambda d: ["run", scene(TINY)(d), "--out", ""], 2, "output directory is empty"),
    Case("out below a file", out_below_file, 2, "afile", "not a directory"),
    Case("out is a file", out_is_file, 2, "afile"),
    Case("out holds other files", out_is_scene_dir, 2, "scene.toml", "no clockwork result"),
    Case("out is the root", out_is_root, 2, "no clockwork result"),
    # --- the cache
    Case("cache is a file", cache_is_file, 0),
    # --- simulations and FMU state
    Case("inconsistent escapement window", run_scene(CHRONOMETER.replace('"-2 deg"', '"3 deg"')), 2, "scene.toml",
         "alpha_m1"),
    Case("diverging co-simulation", run_scene(DIVERGING), 1, "exceeds the divergence limit"),
]

if os.geteuid() != 0:  # root reads and writes through any mode bits
    CASES.append(Case("scene unreadable", scene_unreadable, 2, "scene.toml"))


@pytest.fixture
def hostile_env(tmp_path, monkeypatch):
    fmu_file("Pendulum")
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))
    monkeypatch.setenv("CLOCKWORK_CACHE", str(tmp_path / "cache"))
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_hostile_input(hostile_env, capsys, monkeypatch, case):
    monkeypatch.setenv("CLOCKWORK_CACHE", os.environ["CLOCKWORK_CACHE"])  # restored even if the case changes it
    argv = [str(a) for a in case.build(hostile_env)]
    rc = cli.main(argv)
    out, err = capsys.readouterr()
    assert "Traceback" not in err and "Traceback" not in out
    assert rc == case.code, (rc, err)
    lines = err.strip().splitlines()
    if case.code == 0:
        assert all(not ln.startswith("clockwork: error") for ln in lines), err
        return
    assert len(lines) == 1, err
    assert lines[0].startswith("clockwork: error: "), err
    for needle in case.needles:
        assert needle in lines[0], (needle, lines[0])
    if case.code == 2:  # refused before anything was written
        for out_dir in (hostile_env / "out", hostile_env / "o"):
            assert not out_dir.exists() or not any(out_dir.iterdir()), sorted(out_dir.iterdir())


def test_the_table_is_large_enough():
    assert len(CASES) >= 40


def test_stall_is_a_result(tmp_path, capsys, monkeypatch):
    """A recoil the drive cannot pass stops the clock: exit 0, strict JSON, the stall reported."""
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))
    monkeypatch.setenv("CLOCKWORK_CACHE", "off")
    text = CLOCK.replace('phi_r = "2 deg"', 'phi_r = "4 deg"').replace('torque = "0.4 N.cm"', 'torque = "0.05 N.cm"')
    f = tmp_path / "stall.toml"
    f.write_text(text.replace('kind = "time_series"', 'kind = "steady_state"\namplitude_guess = "5 deg"'))
    rc = cli.main(["run", str(f), "--out", str(tmp_path / "out"), "--no-progress"])
    out, err = capsys.readouterr()
    assert rc == 0, err
    summary = (tmp_path / "out" / "summary.json").read_text()
    parsed = json.loads(summary, parse_constant=lambda c: pytest.fail(f"non-strict JSON constant {c}"))
    assert parsed["result"]["stalled"] is True
    assert "stalled: " in out


@pytest.mark.parametrize("option", [["--workers", "2"], ["--scheduler", "tcp://127.0.0.1:1"]])
def test_sweep_options_on_a_single_run_are_not_ignored_silently(hostile_env, capsys, option):
    rc = cli.main(["run", str(scene(TINY)(hostile_env)), "--out", str(hostile_env / "out"), "--no-progress",
                   *option])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 0 and len(err) == 1 and err[0].startswith("clockwork: warning: " + option[0]), err


@pytest.mark.parametrize("where", ["a file", "below a file", "/proc"])
def test_an_unusable_cache_is_one_warning_not_one_per_point(hostile_env, capsys, monkeypatch, where):
    (hostile_env / "afile").write_text("x")
    cache = {"a file": hostile_env / "afile", "below a file": hostile_env / "afile" / "sub",
             "/proc": Path("/proc/clockwork-cache")}[where]
    monkeypatch.setenv("CLOCKWORK_CACHE", str(cache))
    rc = cli.main(["run", str(scene(SWEPT)(hostile_env)), "--out", str(hostile_env / "out"), "--no-progress",
                   "--workers", "1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 0 and len(err) == 1 and err[0].startswith("clockwork: warning: the point cache"), err
    assert str(cache) in err[0]
