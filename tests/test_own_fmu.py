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
from clockwork.scene.fmu import experiment_times
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
    ("x=2", "TestDecay.x is an output; expected a parameter or an unconnected input"),
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
    if experiment is not None:
        xml = xml.replace("<ModelVariables>", experiment + "<ModelVariables>", 1)
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
