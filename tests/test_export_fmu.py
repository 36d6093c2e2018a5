"""clockwork export-fmu: a scene as one FMI 2.0 Co-Simulation FMU with the
compiled master inside. fmpy validates it and runs it with the scene's step
as its output interval, and gets `clockwork run`'s numbers at the same
communication points, to the bit; bad input is one line, exit 2, and no file."""

from __future__ import annotations

import math
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from cwtest import ROOT as REPO

from clockwork.analyses.time_series import time_series
from clockwork.run.catalog import load_scene
from clockwork.run.export_fmu import export_fmu, system_library

pytestmark = pytest.mark.skipif(not system_library().is_file(),
                                reason="the exported FMU's binary is not built (tools/setup.sh)")

SCENARIOS = REPO / "scenarios"


def _cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "clockwork", *args], capture_output=True, text=True, cwd=cwd,
                          timeout=600)


def _scene_with_record(tmp_path: Path, source: Path, outputs: list[str], stop: str | None = None) -> Path:
    """A copy of a bundled scene with [record] outputs (and a shorter stop), its FMUs by model name."""
    text = source.read_text()
    if stop is not None:
        text = text.replace('stop = "202 s"', f'stop = "{stop}"').replace('stop = "20 s"', f'stop = "{stop}"')
    if "[record]" not in text:
        text += "\n[record]\noutputs = [" + ", ".join(f'"{o}"' for o in outputs) + "]\n"
    path = tmp_path / source.name
    path.write_text(text)
    return path


def _compare(scene_path: Path, fmu: Path):
    """The exported FMU in fmpy against clockwork's time series at the grid points both have."""
    from fmpy import simulate_fmu

    scene = load_scene(scene_path)
    ours = time_series(scene, {})
    series = ours["series"]
    step = scene.master.step
    start, stop = scene.experiment.start, scene.experiment.stop
    theirs = simulate_fmu(str(fmu), start_time=start, stop_time=stop, output_interval=step)
    k_theirs = {round((t - start) / step): i for i, t in enumerate(theirs["time"])}
    compared = 0
    for row, t in enumerate(series["time"]):
        k = (t - start) / step
        if abs(k - round(k)) > 1e-6:  # an event point off the grid: fmpy has no row there
            continue
        i = k_theirs[round(k)]
        for inst, var in scene.record.outputs:
            a, b = series[f"{inst}.{var}"][row], theirs[f"{inst}.{var}"][i]
            assert a == b or (math.isnan(a) and math.isnan(b)), \
                f"{inst}.{var} at t = {t!r} s: clockwork {a!r}, exported FMU {b!r}"
        compared += 1
    return compared


def test_core_grasshopper_gives_clockworks_numbers(tmp_path):
    """The pendulum with the grasshopper escapement (event location, prediction,
    rollback): every recorded output at every recorded grid point, to the bit."""
    scene = _scene_with_record(tmp_path, SCENARIOS / "core_grasshopper.toml", [], stop="20 s")
    out = tmp_path / "clock.fmu"
    r = _cli("export-fmu", str(scene), "--out", str(out))
    assert r.returncode == 0, r.stderr
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(out)) == []
    assert _compare(scene, out) > 300


def test_free_pendulum_gives_clockworks_numbers(tmp_path):
    scene = _scene_with_record(tmp_path, REPO / "clockwork/kit/scenes/free_pendulum.toml",
                               ["pendulum.phi", "pendulum.w"], stop="5 s")
    out = tmp_path / "free.fmu"
    export_fmu(scene, out)
    assert _compare(scene, out) > 400


def test_variables_and_experiment(tmp_path):
    """Parameters by instance name with the inner FMUs' units and descriptions,
    recorded outputs, open inputs, the scene's DefaultExperiment."""
    from fmpy import read_model_description

    out = tmp_path / "clock.fmu"
    export_fmu(SCENARIOS / "core_grasshopper.toml", out)
    md = read_model_description(str(out))
    v = {x.name: x for x in md.modelVariables}
    assert v["pendulum.Q"].causality == "parameter" and float(v["pendulum.Q"].start) == 1000.0
    assert v["pendulum.L"].unit == "m" and v["pendulum.L"].description
    assert v["escapement.torque"].start is not None and float(v["escapement.torque"].start) == pytest.approx(0.004)
    assert [x.variable.name for x in md.outputs] == ["pendulum.phi", "pendulum.w", "escapement.tau"]
    assert md.coSimulation.canHandleVariableCommunicationStepSize
    assert md.defaultExperiment.stepSize == "0.01" or float(md.defaultExperiment.stepSize) == 0.01
    assert float(md.defaultExperiment.stopTime) == 202.0
    names = zipfile.ZipFile(out).namelist()
    assert "resources/clockwork/system.txt" in names
    assert not any(n.endswith(".py") for n in names)  # no Python inside


def test_a_changed_parameter_changes_the_run(tmp_path):
    """A parameter set by the importer reaches the inner FMU (as --set does in clockwork run)."""
    from fmpy import simulate_fmu

    scene = _scene_with_record(tmp_path, REPO / "clockwork/kit/scenes/free_pendulum.toml",
                               ["pendulum.phi"], stop="1 s")
    set_scene = tmp_path / "set.toml"
    set_scene.write_text(scene.read_text().replace('fmu = "Pendulum"',
                                                   'fmu = "Pendulum"\nparameters = { L = "1 m" }'))
    out = tmp_path / "free.fmu"
    export_fmu(set_scene, out)
    a = simulate_fmu(str(out), stop_time=1.0, output_interval=0.01)
    b = simulate_fmu(str(out), stop_time=1.0, output_interval=0.01, start_values={"pendulum.L": 0.5})
    assert a["pendulum.phi"][-1] != b["pendulum.phi"][-1]
    ours = time_series(load_scene(set_scene, ["pendulum.L=0.5 m"]), {})["series"]
    assert ours["pendulum.phi"][-1] == b["pendulum.phi"][-1]


@pytest.mark.parametrize("case", ["sweep", "analysis", "exists", "not_writable", "suffix"])
def test_bad_input_is_one_line_and_no_file(tmp_path, case):
    out = tmp_path / "x.fmu"
    scene = str(SCENARIOS / "core_grasshopper.toml")
    if case == "sweep":
        scene = str(SCENARIOS / "ziemkiewicz_fig1.toml")
    elif case == "analysis":
        scene = str(SCENARIOS / "hoyng_fig3.toml")
    elif case == "exists":
        out.write_bytes(b"keep")
    elif case == "not_writable":
        if os.geteuid() == 0:
            pytest.skip("root writes anywhere")
        d = tmp_path / "ro"
        d.mkdir()
        d.chmod(0o500)
        out = d / "x.fmu"
    elif case == "suffix":
        out = tmp_path / "x.zip"
    r = _cli("export-fmu", scene, "--out", str(out))
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("clockwork: error: "), r.stderr
    if case == "exists":
        assert out.read_bytes() == b"keep"
    else:
        assert not out.exists()
    assert not [p for p in out.parent.iterdir() if p.name.endswith(".part")]


def test_fmu_without_a_linux_binary_is_refused(tmp_path):
    """An inner FMU that carries no binary for the exported FMU's platform: refused at export."""
    src = REPO / "fmus" / "Pendulum.fmu"
    stripped = tmp_path / "Pendulum.fmu"
    with zipfile.ZipFile(src) as a, zipfile.ZipFile(stripped, "w") as b:
        for item in a.infolist():
            if not item.filename.startswith("binaries/linux64/"):
                b.writestr(item, a.read(item))
    out = tmp_path / "x.fmu"
    r = _cli("export-fmu", str(stripped), "--out", str(out))
    assert r.returncode == 2
    assert len(r.stderr.strip().splitlines()) == 1 and "linux64" in r.stderr, r.stderr
    assert not out.exists()
