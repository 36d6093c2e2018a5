"""clockwork export-fmu: a scene as one FMI 2.0 Co-Simulation FMU with the
compiled master inside. fmpy validates it and runs it with the scene's step
as its output interval, and gets `clockwork run`'s numbers at the same
communication points, to the bit; bad input is one line, exit 2, and no file."""

from __future__ import annotations

import dataclasses
import math
import os
import re
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
        text = re.sub(r'(?m)^stop = .*$', f'stop = "{stop}"', text, count=1)
    if "[record]" not in text:
        text += "\n[record]\noutputs = [" + ", ".join(f'"{o}"' for o in outputs) + "]\n"
    path = tmp_path / source.name
    path.write_text(text)
    return path


def _compare(spec, fmu: Path, overrides=()) -> int:
    """The exported FMU in fmpy, with the scene's step as its output
    interval, against clockwork's time series of the same scene at every
    grid point (clockwork's rows at events off the grid have no fmpy row):
    every exported output, to the bit. Returns the points compared."""
    from fmpy import read_model_description, simulate_fmu

    scene = load_scene(spec, overrides)
    outputs = [v.name for v in read_model_description(str(fmu)).modelVariables if v.causality == "output"]  # FMI 2.0, 3.0
    assert outputs
    # clockwork's run recording what the exported FMU outputs (the same list when the scene records any)
    record = dataclasses.replace(scene.record, outputs=tuple(tuple(o.split(".", 1)) for o in outputs))
    series = time_series(dataclasses.replace(scene, record=record), {})["series"]
    step = scene.master.step
    start, stop = scene.experiment.start, scene.experiment.stop
    theirs = simulate_fmu(str(fmu), start_time=start, stop_time=stop, output_interval=step)
    k_theirs = {round((t - start) / step): i for i, t in enumerate(theirs["time"])}
    compared = 0
    for row, t in enumerate(series["time"]):
        k = (t - start) / step
        if abs(k - round(k)) > 1e-6:
            continue
        i = k_theirs[round(k)]
        for name in outputs:
            a, b = series[name][row], theirs[name][i]
            assert a == b or (math.isnan(a) and math.isnan(b)), \
                f"{name} at t = {t!r} s: clockwork {a!r}, exported FMU {b!r}"
        compared += 1
    return compared


def _export(spec, out: Path, overrides=(), fmi: int = 2) -> None:
    r = _cli("export-fmu", str(spec), "--out", str(out), "--fmi", str(fmi),
             *[x for o in overrides for x in ("--set", o)])
    assert r.returncode == 0, r.stderr
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(out)) == []


# Every bundled scene that is a time series (docs/other-tools.md lists the others), shortened.
TIME_SERIES = [
    (SCENARIOS / "core_grasshopper.toml", "20 s"),
    (SCENARIOS / "core_grasshopper_drag.toml", "10 s"),
    (SCENARIOS / "core_vibration.toml", "10 s"),
    (REPO / "clockwork/kit/scenes/chronometer.toml", "10 s"),
    (REPO / "clockwork/kit/scenes/free_pendulum.toml", "5 s"),
    (REPO / "clockwork/kit/scenes/hoyng_jump.toml", "10 s"),
]


@pytest.mark.parametrize("fmi", [2, 3])
@pytest.mark.parametrize("source,stop", TIME_SERIES, ids=[p.stem for p, _ in TIME_SERIES])
def test_bundled_time_series_give_clockworks_numbers(tmp_path, source, stop, fmi):
    overrides = [f"experiment.stop={stop}"]
    out = tmp_path / "x.fmu"
    _export(source, out, overrides, fmi)
    if fmi == 3:
        from fmpy import read_model_description

        md = read_model_description(str(out))
        assert md.fmiVersion == "3.0" and md.coSimulation.canHandleVariableCommunicationStepSize
    n = _compare(source, out, overrides)
    step = load_scene(source).master.step
    assert n >= int(float(stop.split()[0]) / step / 10)  # at least every record interval's point


def test_fmu_alone_and_ssp_give_clockworks_numbers(tmp_path):
    """An FMU alone (its DefaultExperiment, every output) and an SSP export of a scene."""
    out = tmp_path / "alone.fmu"
    pendulum = REPO / "fmus" / "Pendulum.fmu"
    _export(pendulum, out, ["experiment.stop=3"])
    assert _compare(pendulum, out, ["experiment.stop=3"]) > 0
    ssp = tmp_path / "clock.ssp"
    assert _cli("export-ssp", str(SCENARIOS / "core_grasshopper.toml"), "--out", str(ssp)).returncode == 0
    out = tmp_path / "ssp.fmu"
    _export(ssp, out, ["experiment.stop=5"])
    assert _compare(ssp, out, ["experiment.stop=5"]) > 50


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
    again = tmp_path / "again.fmu"
    export_fmu(SCENARIOS / "core_grasshopper.toml", again)
    assert again.read_bytes() == out.read_bytes()  # the same scene, the same bytes (and GUID)


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


@pytest.mark.parametrize("case", ["sweep", "analysis", "exists", "not_writable", "suffix", "no_directory",
                                  "fmi3_inner", "richardson"])
def test_bad_input_is_one_line_and_no_file(tmp_path, case):
    out = tmp_path / "x.fmu"
    scene = str(SCENARIOS / "core_grasshopper.toml")
    sets = {"fmi3_inner": ["--set", "master.fmi_version=3"],  # the FMUs' FMI 3.0 builds: the front calls FMI 2.0
            "richardson": ["--set", "master.richardson=true"]}.get(case, [])
    if case == "sweep":
        scene = str(SCENARIOS / "ziemkiewicz_fig1.toml")
    elif case == "analysis":
        scene = str(SCENARIOS / "ziemkiewicz_fig3.toml")  # steady_orbit, no sweep
    elif case == "exists":
        out.write_bytes(b"keep")
    elif case == "not_writable":
        if os.geteuid() == 0:  # root writes into any folder it may enter: /proc takes no new file
            out = Path("/proc/x.fmu")
        else:
            d = tmp_path / "ro"
            d.mkdir()
            d.chmod(0o500)
            out = d / "x.fmu"
    elif case == "suffix":
        out = tmp_path / "x.zip"
    elif case == "no_directory":
        out = tmp_path / "a" / "b" / "x.fmu"
    r = _cli("export-fmu", scene, "--out", str(out), *sets)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("clockwork: error: "), r.stderr
    if case == "exists":
        assert out.read_bytes() == b"keep"
    else:
        assert not out.exists()
    if out.parent.is_dir() and out.parent != Path("/proc"):
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


def test_open_inputs(tmp_path):
    """An unconnected input is an input of the exported FMU: set before
    initialization it gives clockwork's numbers for the same value set by
    --set; changed between steps, it reaches the FMU from then on."""
    from fmpy import simulate_fmu

    source = REPO / "clockwork/kit/scenes/free_pendulum.toml"
    out = tmp_path / "free.fmu"
    export_fmu(source, out, overrides=["experiment.stop=3"])
    scene = load_scene(source, ["experiment.stop=3", "pendulum.tau_escapement=0.001"])
    scene = dataclasses.replace(scene, record=dataclasses.replace(scene.record, outputs=(("pendulum", "phi"),)))
    ours = time_series(scene, {})["series"]["pendulum.phi"]
    theirs = simulate_fmu(str(out), stop_time=3.0, output_interval=0.01,
                          start_values={"pendulum.tau_escapement": 0.001}, output=["pendulum.phi"])
    assert list(theirs["pendulum.phi"]) == list(ours[:len(theirs)]) and len(ours) == len(theirs)
    free = simulate_fmu(str(out), stop_time=3.0, output_interval=0.01, output=["pendulum.phi"])
    signal = np.array([(0.0, 0.0), (1.0, 0.0), (1.0, 0.002), (3.0, 0.002)],
                      dtype=[("time", float), ("pendulum.tau_escapement", float)])
    pushed = simulate_fmu(str(out), stop_time=3.0, output_interval=0.01, input=signal, output=["pendulum.phi"])
    assert list(pushed["pendulum.phi"][:101]) == list(free["pendulum.phi"][:101])  # the same until t = 1 s
    assert pushed["pendulum.phi"][-1] != free["pendulum.phi"][-1]


@pytest.mark.parametrize("fmi", [2, 3])
def test_fmu_state_rolls_the_system_back(tmp_path, fmi):
    """fmi2GetFMUstate/SetFMUstate (fmi3GetFMUState/SetFMUState) and their
    serialization: a rolled-back exported clock (events located, checkpoints
    held by its master) steps again to the same bits; the serialized state
    too, in a second instance."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    from fmpy.fmi3 import FMU3Slave

    out = tmp_path / "clock.fmu"
    export_fmu(SCENARIOS / "core_grasshopper.toml", out, fmi=fmi)
    md = read_model_description(str(out))
    assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate
    unzip = extract(str(out))
    vrs = [v.valueReference for v in md.modelVariables if v.causality == "output"]

    def started(name):
        kind = FMU2Slave if fmi == 2 else FMU3Slave
        key = {"guid": md.guid} if fmi == 2 else {"guid": md.instantiationToken}
        s = kind(unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name, **key)
        s.instantiate()
        if fmi == 2:
            s.setupExperiment(startTime=0.0)
            s.enterInitializationMode()
        else:
            s.enterInitializationMode(startTime=0.0)
        s.exitInitializationMode()
        return s

    def run(s, k0, k1):
        rows = []
        for k in range(k0, k1):
            s.doStep(k * 0.01, (k + 1) * 0.01 - k * 0.01)
            rows.append(tuple(s.getReal(vrs) if fmi == 2 else s.getFloat64(vrs)))
        return rows

    get, put, free = (("getFMUstate", "setFMUstate", "freeFMUstate") if fmi == 2 else
                      ("getFMUState", "setFMUState", "freeFMUState"))
    pack, unpack = (("serializeFMUstate", "deSerializeFMUstate") if fmi == 2 else
                    ("serializeFMUState", "deserializeFMUState"))
    a = started("a")
    run(a, 0, 300)
    state = getattr(a, get)()
    first = run(a, 300, 700)
    getattr(a, put)(state)
    assert run(a, 300, 700) == first
    blob = getattr(a, pack)(state)
    getattr(a, free)(state)
    b = started("b")
    run(b, 0, 10)  # elsewhere, then the serialized state of a at 3 s
    restored = getattr(b, unpack)(blob)
    getattr(b, put)(restored)
    assert run(b, 300, 700) == first
    getattr(b, free)(restored)
    for s in (a, b):
        s.terminate()
        s.freeInstance()


def test_two_instances_of_one_fmu(tmp_path):
    """Two pendulums of one FMU (unpacked once, instantiated twice), one
    driving the other through a scaled link: clockwork's numbers."""
    scene = tmp_path / "two.toml"
    scene.write_text('''connections = ["a.energy -> b.tau_external"]

[scene]
title = "Two pendulums of one FMU"

[components.a]
fmu = "Pendulum"
parameters = { Q = 100, phi_start = "5 deg" }

[components.b]
fmu = "Pendulum"
parameters = { Q = 50, phi_start = "2 deg", L = "0.5 m" }

[experiment]
start = 0.0
stop = "3 s"

[master]
step = "0.01 s"
extrapolation = 1

[record]
outputs = ["a.phi", "b.phi", "b.w"]
''')
    out = tmp_path / "two.fmu"
    _export(scene, out)
    assert sum(1 for n in zipfile.ZipFile(out).namelist() if n.endswith("Pendulum.so")) == 1
    assert _compare(scene, out) == 301


@pytest.mark.parametrize("fmi", [2, 3])
def test_windows_binary_under_wine(tmp_path, fmi):
    """The exported FMU's Windows front (mingw-w64, cmake/cross.cmake) with the
    inner FMUs' win64 DLLs, run under wine by the platform harness
    (tools/platcheck/harness.c), against the Linux binary run by the same
    harness: the same points and the same bits."""
    import shutil

    from cwtest import BUILD_DIR

    sys.path.insert(0, str(REPO / "tools" / "platcheck"))
    import platcheck

    harness, harness_exe = BUILD_DIR / "platcheck", BUILD_DIR / "x86_64-windows" / "platcheck.exe"
    if not (system_library(".dll").is_file() and harness_exe.is_file() and shutil.which("wine")):
        if os.environ.get("CI"):
            pytest.fail("the Windows build or wine is missing in CI: tools/setup.sh installs them")
        pytest.skip("the Windows build (mingw-w64) or wine is missing")
    out = tmp_path / "clock.fmu"
    export_fmu(SCENARIOS / "core_grasshopper.toml", out, overrides=["experiment.stop=5"], fmi=fmi)
    linux, windows = platcheck.FOLDERS["linux"][fmi], platcheck.FOLDERS["windows"][fmi]
    assert f"binaries/{windows}/core_grasshopper.dll" in zipfile.ZipFile(out).namelist()
    unzip = tmp_path / "unzip"
    zipfile.ZipFile(out).extractall(unzip)
    f = platcheck.describe(out)
    times = [platcheck._bits(x) for x in (f.start, f.stop, f.step, 0.0)]
    vrs = ",".join(map(str, f.vrs))
    resources = unzip / "resources"  # FMI 2.0: a file URI; FMI 3.0: a path
    (tmp_path / "linux.txt").write_text("\t".join(
        [str(fmi), str(unzip / f"binaries/{linux}/core_grasshopper.so"), f.token,
         resources.as_uri() + "/" if fmi == 2 else str(resources) + "/", *times, vrs]) + "\n")
    (tmp_path / "windows.txt").write_text("\t".join(
        [str(fmi), "Z:" + (unzip / f"binaries/{windows}/core_grasshopper.dll").as_posix(), f.token,
         ("file:///Z:" if fmi == 2 else "Z:") + resources.as_posix() + "/", *times, vrs]) + "\n")
    prefix = tmp_path / "wineprefix"
    try:
        native = platcheck.run_native(harness, ["linux.txt"], tmp_path)
        wine = platcheck.run_wine(harness_exe, ["windows.txt"], tmp_path, prefix)
    finally:
        platcheck.stop_wineserver(prefix)
    a, b = native.runs[0], wine.runs[0]
    assert a.end == "ok" and b.end == "ok", (a.end, b.end)
    assert a.points.shape == b.points.shape and a.points.shape[0] == 501
    assert np.array_equal(a.points[:, 0], b.points[:, 0])  # the same communication points
    # The inner FMUs' C library calls give glibc's bits on this run (tests/test_platforms.py names the
    # arguments where mingw-w64's differ in the last bit); the master's arithmetic is IEEE on both.
    assert np.array_equal(a.points, b.points)


def test_an_inner_refusal_is_the_importers_error(tmp_path):
    """A parameter an inner FMU refuses: fmi2ExitInitializationMode fails,
    with the inner FMU's own message passed on to the importer's logger."""
    import concurrent.futures
    import multiprocessing

    out = tmp_path / "clock.fmu"
    export_fmu(SCENARIOS / "core_grasshopper.toml", out, overrides=["experiment.stop=1"])
    # In a process of its own: fmpy keeps the logger given to simulate_fmu in
    # its logging proxy's global state, which outlives the call (the FMU fmpy
    # never frees after the failed initialization too); a later FMU's message
    # in this process would call a freed callback.
    with concurrent.futures.ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        error, said = pool.submit(_refused_initialization, str(out)).result(timeout=600)
    assert "fmi2ExitInitializationMode" in error
    assert any("pendulum" in m and "L = -1" in m for m in said), said


def _refused_initialization(fmu: str):
    """simulate_fmu with a parameter an inner FMU refuses: (the error, the
    messages the importer's logger got)."""
    from fmpy import simulate_fmu

    said = []
    try:
        simulate_fmu(fmu, stop_time=1.0, output_interval=0.01, start_values={"pendulum.L": -1.0},
                     logger=lambda *args: said.append(args[-1].decode() if isinstance(args[-1], bytes) else args[-1]))
    except Exception as e:
        return str(e), said
    return "", said


def test_clockwork_runs_the_exported_fmu_with_its_own_numbers(tmp_path):
    """clockwork as the importer (`clockwork run X.fmu`: the FMU alone, its
    DefaultExperiment's step): the scene's numbers again, at every grid point."""
    out = tmp_path / "clock.fmu"
    export_fmu(SCENARIOS / "core_grasshopper.toml", out, overrides=["experiment.stop=5"])
    ours = time_series(load_scene(SCENARIOS / "core_grasshopper.toml", ["experiment.stop=5"]), {})["series"]
    alone = time_series(load_scene(out), {})["series"]
    prefix = "core_grasshopper."  # the FMU alone's instance, named after its model
    rows = {round(t / 0.01): k for k, t in enumerate(alone["time"])}
    compared = 0
    for k, t in enumerate(ours["time"]):
        if abs(t / 0.01 - round(t / 0.01)) < 1e-6:
            j = rows[round(t / 0.01)]
            for name in ("pendulum.phi", "pendulum.w", "escapement.tau"):
                assert ours[name][k] == alone[prefix + name][j], (name, t)
            compared += 1
    assert compared == 101


@pytest.mark.parametrize("tool", ["libcosim", "ecos"])
def test_other_masters_get_clockworks_numbers(tmp_path, tool):
    """libcosim (libcosimpy, time in ns) and ecos (ecospy) step the exported
    clock with the scene's step: clockwork's value at the end, to the bit."""
    out = tmp_path / "clock.fmu"
    export_fmu(SCENARIOS / "core_grasshopper.toml", out, overrides=["experiment.stop=5"])
    ours = time_series(load_scene(SCENARIOS / "core_grasshopper.toml", ["experiment.stop=5"]), {})["series"]
    if tool == "libcosim":
        pytest.importorskip("libcosimpy")
        from libcosimpy.CosimExecution import CosimExecution
        from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
        from libcosimpy.CosimObserver import CosimObserver
        from libcosimpy.CosimSlave import CosimLocalSlave

        log_output_level(CosimLogLevel.WARNING)
        ex = CosimExecution.from_step_size(step_size=10**7)  # 0.01 s
        i = ex.add_local_slave(local_slave=CosimLocalSlave(fmu_path=str(out), instance_name="clock"))
        observer = CosimObserver.create_last_value()
        ex.add_observer(observer)
        vr = {v.name.decode(): v.reference for v in ex.slave_variables(i)}
        assert ex.simulate_until(5 * 10**9)
        theirs = observer.last_real_values(i, [vr["pendulum.phi"]])[0]
    else:
        pytest.importorskip("ecospy")
        from ecospy import EcosSimulation, EcosSimulationStructure

        structure = EcosSimulationStructure()
        structure.add_model("clock", str(out))
        sim = EcosSimulation(structure=structure, step_size=0.01)
        sim.init()
        sim.step_until(5.0)
        theirs = sim.get_real("clock::pendulum.phi")
        sim.terminate()
    assert theirs == ours["pendulum.phi"][-1]


def test_fmi3_early_return_at_the_inner_events(tmp_path):
    """FMI 3.0 with early return allowed: fmi3DoStep returns at each event its
    master locates inside a step (the escapement's switches), and the grid
    points keep clockwork's numbers to the bit."""
    from fmpy import simulate_fmu

    out = tmp_path / "clock3.fmu"
    export_fmu(SCENARIOS / "core_grasshopper.toml", out, overrides=["experiment.stop=5"], fmi=3)
    theirs = simulate_fmu(str(out), stop_time=5.0, output_interval=0.01, early_return_allowed=True)
    k = theirs["time"] / 0.01
    on_grid = np.abs(k - np.round(k)) < 1e-6
    assert 3 <= int((~on_grid).sum()) <= 20  # one return per switch
    ours = time_series(load_scene(SCENARIOS / "core_grasshopper.toml", ["experiment.stop=5"]), {})["series"]
    rows = {int(round(x)): i for i, x in enumerate(k) if abs(x - round(x)) < 1e-6}
    for j, t in enumerate(ours["time"]):
        if abs(t / 0.01 - round(t / 0.01)) < 1e-6:
            assert ours["pendulum.phi"][j] == theirs["pendulum.phi"][rows[round(t / 0.01)]], t
    plain = simulate_fmu(str(out), stop_time=5.0, output_interval=0.01)
    assert len(plain) == 501  # not allowed: no early return


def test_ssp_with_a_linear_transformation(tmp_path):
    """An SSP whose link carries ssc:LinearTransformation (factor 2: the
    escapement's torque doubled into the pendulum): the link's factor is
    applied by the front in initialization and by the core in the steps,
    and fmpy gets clockwork's numbers."""
    import shutil

    ssp = tmp_path / "flat10"
    shutil.copytree(REPO / "tests/data/ssp/flat10", ssp)
    for name in ("Pendulum", "GrasshopperEscapement"):
        shutil.copy(REPO / "fmus" / f"{name}.fmu", ssp / "resources" / f"{name}.fmu")
    ssd = ssp / "SystemStructure.ssd"
    sets = ["experiment.stop=5", "master.step=0.01"]
    out = tmp_path / "flat10.fmu"
    _export(ssd, out, sets)
    scene = load_scene(ssd, sets)
    assert any(c.factor != 1.0 for c in scene.connections)
    assert _compare(ssd, out, sets) == 501


@pytest.mark.parametrize("fmi", [2, 3])
def test_outputs_in_initialization_mode_are_the_initial_values(tmp_path, fmi):
    """FMI 2.0 and 3.0 let an importer read an output in Initialization
    Mode (its initial value: how a master propagates start values through
    connections). The exported FMU gives the inner FMUs' initial outputs
    there (the pendulum released from 10 deg, its acceleration -g/L sin),
    follows an input set after such a read (a torque: the acceleration
    moves at once), and steps on to the same bits as an importer that never
    read in Initialization Mode (before: 0 until its end)."""
    import math

    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    from fmpy.fmi3 import FMU3Slave

    out = tmp_path / "free.fmu"
    export_fmu(REPO / "clockwork/kit/scenes/free_pendulum.toml", out, overrides=["experiment.stop=1"], fmi=fmi)
    md = read_model_description(str(out))
    unzip = extract(str(out))
    names = {v.name: v.valueReference for v in md.modelVariables}
    phi, a, torque = names["pendulum.phi"], names["pendulum.a"], names["pendulum.tau_external"]

    def run(read_in_init: bool):
        kind = FMU2Slave if fmi == 2 else FMU3Slave
        key = {"guid": md.guid} if fmi == 2 else {"guid": md.instantiationToken}
        s = kind(unzipDirectory=unzip, modelIdentifier=md.coSimulation.modelIdentifier, instanceName="f", **key)
        get = s.getReal if fmi == 2 else s.getFloat64
        put = s.setReal if fmi == 2 else s.setFloat64
        s.instantiate()
        if fmi == 2:
            s.setupExperiment(startTime=0.0)
            s.enterInitializationMode()
        else:
            s.enterInitializationMode(startTime=0.0)
        seen = []
        if read_in_init:
            seen.append(tuple(get([phi, a])))
        put([torque], [0.5])
        if read_in_init:
            seen.append(tuple(get([phi, a])))
        s.exitInitializationMode()
        rows = [tuple(get([phi, a]))]
        for k in range(50):
            s.doStep(k * 0.01, 0.01)
            rows.append(tuple(get([phi, a])))
        s.terminate()
        s.freeInstance()
        return seen, rows

    seen, rows = run(True)
    phi0 = math.radians(10.0)
    assert seen[0][0] == pytest.approx(phi0, rel=1e-15)
    assert seen[0][1] == pytest.approx(-9.81 * math.sin(phi0), rel=1e-12)
    assert seen[1][0] == seen[0][0] and seen[1][1] > seen[0][1]  # the torque's acceleration at once
    assert rows[0] == seen[1]
    assert rows == run(False)[1]


def test_components_at_their_own_steps_are_refused_in_one_line(tmp_path):
    """The front's file carries no rates: a scene with a component at its
    own step is refused, not exported to step every component at master.step."""
    scene = tmp_path / "rates.toml"
    scene.write_text('connections = ["pendulum.phi -> vibration.a1", "vibration.tau -> pendulum.tau_coupling"]\n'
                     '[scene]\ntitle = "two rates"\n[components.pendulum]\nfmu = "Pendulum"\n'
                     '[components.vibration]\nfmu = "MechanismVibration"\nstep = 0.03\n'
                     '[experiment]\nstop = 0.3\n[master]\nstep = 0.01\n')
    out = tmp_path / "x.fmu"
    r = _cli("export-fmu", str(scene), "--out", str(out))
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "components.vibration.step" in lines[0] and "own steps" in lines[0], r.stderr
    assert not out.exists()
