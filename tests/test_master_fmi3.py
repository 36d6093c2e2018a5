"""The master on FMI 3.0 Co-Simulation FMUs, in both engines.

The FMU is tests/data/fmi3/bouncer.c (tests/fmi3_bouncer.py describes it, CMake builds it): x
runs between the walls 0 and 1 at speed v0 (+ the input u), so every event
time is known in closed form: wall hits (the FMU's own state events, early
return), time events at k * period (nextEventTime), the crossing of z = x -
threshold (an indicator the master locates with rollback), and the end the
FMU asks for after n_stop time events (terminateSimulation). The bundled
FMUs' FMI 3.0 builds (fmus/fmi3/) are compared with their FMI 2.0 builds
where they exist.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import zipfile

import pytest

from clockwork.engine import MasterSettings, System
from clockwork.fmi.description import FmuError, read_fmu
from clockwork.engine.recording import Recorder
from clockwork.errors import SceneError, SimulationEnded
from cwtest import FMU_DIR, test_fmu

ENGINES = ("python", "compiled")


@pytest.fixture(scope="module")
def fmus():
    """The bouncer's builds (fmi3_bouncer.description, tests/CMakeLists.txt)."""
    return {name.lower(): test_fmu(f"fmi3/{name}") for name in ("Early", "Inside", "Indicator", "Refusing")}


def triangle(t: float, v0: float) -> float:
    """x of the bouncer without input: 0 -> 1 -> 0 at speed v0."""
    s = (v0 * t) % 2.0
    return s if s <= 1.0 else 2.0 - s


def run(path, params, stop, step, engine, outputs=("x", "n", "bounces"), **settings):
    with System({"b": (str(path), params)}, [], MasterSettings(step=step, engine=engine, **settings),
                record={"b": list(outputs)}) as s:
        rec = Recorder(s.master, [("b", o) for o in outputs])
        rec.start()
        s.master.run_until(stop, rec)  # an FMU's end is a clean end: master.ended says it
        ended = s.master.ended
        ev = s.instances["b"].events
        return rec.columns, vars(s.master.stats).copy(), (ev.early_returns, ev.events), ended


@pytest.mark.parametrize("engine", ENGINES)
def test_early_return_lands_the_fmus_own_events_exactly(fmus, engine):
    """Wall hits inside 0.5 s steps (v0 = 0.7: at 1/0.7, 2/0.7 ... s) are
    handled at lastSuccessfulTime in event mode: x follows the triangle to
    1e-12 at every point, with no rollback."""
    cols, stats, (early, events), ended = run(fmus["early"], {"v0": 0.7, "period": 0.0}, 6.0, 0.5, engine)
    assert ended is None
    assert early == 4 and events == 1 + 4  # initialization, then walls at 1.43, 2.86, 4.29, 5.71 s
    assert stats["rollbacks"] == 0 and stats["states_saved"] == 0
    assert cols["time"][-1] == 6.0
    for t, x in zip(cols["time"], cols["b.x"]):
        assert abs(x - triangle(t, 0.7)) < 1e-12, t
    assert cols["b.bounces"][-1] == 4.0


def test_early_return_and_handling_inside_the_step_agree(fmus):
    """The same FMU handling its events inside fmi3DoStep (no event mode)
    gives the same trajectory: early return loses nothing."""
    a = run(fmus["early"], {"v0": 0.7, "period": 0.0}, 6.0, 0.5, "python")[0]
    b = run(fmus["inside"], {"v0": 0.7, "period": 0.0}, 6.0, 0.5, "python")[0]
    assert a["time"] == b["time"]
    assert max(abs(x - y) for x, y in zip(a["b.x"], b["b.x"])) < 1e-12


@pytest.mark.parametrize("engine", ENGINES)
def test_next_event_time_lands_a_communication_point(fmus, engine):
    """Time events every 0.3 s with a 0.25 s step: each is a communication
    point, and n has counted it there."""
    cols, _, _, _ = run(fmus["early"], {"v0": 1.0, "period": 0.3}, 2.0, 0.25, engine)
    times = cols["time"]
    for k in range(1, 7):
        te = 0.3 * k
        near = [i for i, t in enumerate(times) if abs(t - te) < 1e-12]
        assert near, f"no communication point at {te}"
        assert cols["b.n"][near[0]] == k
    assert all(n == math.floor(t / 0.3 + 1e-9) for t, n in zip(times, cols["b.n"]))


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("fmu, last_point", [("early", 1.25), ("inside", 1.2)])
def test_terminate_simulation_ends_the_run_where_the_fmu_says(fmus, engine, fmu, last_point):
    """The 5th time event (1.25 s) ends the run. In event mode it is a
    communication point and the step to it stands; handled inside a step
    (1.2 -> 1.3 s) that step is not taken, and the run ends at 1.2 s."""
    cols, _, _, ended = run(fmus[fmu], {"v0": 1.0, "period": 0.25, "n_stop": 5}, 10.0, 0.1, engine)
    assert isinstance(ended, SimulationEnded)
    assert ended.instance == "b" and abs(ended.fmu_time - 1.25) < 1e-12
    assert abs(ended.time - last_point) < 1e-12  # the last communication point
    assert "terminateSimulation" in str(ended)
    assert abs(cols["time"][-1] - last_point) < 1e-12  # what was recorded before the end is kept


@pytest.mark.parametrize("engine", ENGINES)
def test_master_locates_an_fmi3_indicator_with_rollback(fmus, engine):
    """z = x - 0.5 crosses zero at 0.5, 1.5, 2.5 s (v0 = 1): the master
    locates each with FMU state restores, to 1e-10 s; the announced time
    events survive the restores (they still land at k * 0.4 s)."""
    cols, stats, _, _ = run(fmus["indicator"], {"v0": 1.0, "period": 0.4}, 3.0, 0.3, engine)
    assert stats["events"] == 3 and stats["rollbacks"] > 0
    for tc in (0.5, 1.5, 2.5):
        after = min(t for t in cols["time"] if t >= tc - 1e-10)
        assert after - tc < 1e-9, tc
    for k in range(1, 8):
        assert any(abs(t - 0.4 * k) < 1e-12 for t in cols["time"]), k
    for t, x in zip(cols["time"], cols["b.x"]):
        assert abs(x - triangle(t, 1.0)) < 1e-12, t


def test_both_engines_give_the_same_bits(fmus):
    for params, stop, step in (({"v0": 0.7, "period": 0.0}, 6.0, 0.5), ({"v0": 1.0, "period": 0.3}, 2.0, 0.25)):
        for key in ("early", "indicator"):
            a = run(fmus[key], params, stop, step, "python")
            b = run(fmus[key], params, stop, step, "compiled")
            assert a[0] == b[0] and a[1] == b[1] and a[2] == b[2]


@pytest.mark.parametrize("engine", ENGINES)
def test_mixed_fmi2_and_fmi3(fmus, engine, fmu_dir):
    """The FMI 2.0 Pendulum drives the FMI 3.0 bouncer's input; both engines
    give the same bits, and the bouncer integrates the pendulum's angle."""
    def go(engine):
        with System({"pendulum": (str(fmu_dir / "Pendulum.fmu"), {"phi_start": 0.1}),
                     "b": (str(fmus["early"]), {"v0": 0.0, "period": 0.0})},
                    ["pendulum.phi -> b.u"], MasterSettings(step=0.01, engine=engine),
                    record={"b": ["x"], "pendulum": ["phi"]}) as s:
            rec = Recorder(s.master, [("b", "x"), ("pendulum", "phi")])
            rec.start()
            s.master.run_until(0.4, rec)  # phi > 0 throughout: x never reaches a wall
            return rec.columns
    cols = go(engine)
    assert cols == go("python")
    # x' = phi held over each 10 ms step; in Gauss-Seidel order the bouncer
    # steps after the pendulum and holds its newest value, phi at the step's end.
    expect = 0.0
    for phi in cols["pendulum.phi"][1:]:
        expect += phi * 0.01
    assert abs(cols["b.x"][-1] - expect) < 1e-12
    assert cols["b.x"][-1] > 0.02  # the input did arrive


@pytest.mark.parametrize("key, value", [("extrapolation", 1), ("iterations", 2)])
def test_polynomial_inputs_into_fmi3_are_refused(fmus, fmu_dir, tmp_path, key, value):
    """FMI 3.0 CS has no input derivatives: extrapolation and strong coupling
    into an FMI 3.0 FMU without intermediate update are refused by the
    engine and, in a scene, in one line naming the file and the key."""
    with pytest.raises(SceneError, match=f"master.{key} = {value}: b .* FMI 3.0 FMU, whose Co-Simulation "
                                         "interface takes no input derivatives, and it provides no intermediate "
                                         "update"):
        System({"pendulum": (str(fmu_dir / "Pendulum.fmu"), {}), "b": (str(fmus["early"]), {})},
               ["pendulum.phi -> b.u"], MasterSettings(step=0.01, **{key: value}))
    scene = tmp_path / "s.toml"
    scene.write_text(f'connections = ["a.x -> b.u"]\n[scene]\ntitle = "t"\n'
                     f'[components.a]\nfmu = "{fmus["early"]}"\n'
                     f'[components.b]\nfmu = "{fmus["early"]}"\n[experiment]\nstop = 1\n'
                     f'[master]\n{key} = {value}\n')
    p = subprocess.run([sys.executable, "-m", "clockwork", "validate", str(scene)], capture_output=True, text=True)
    assert p.returncode == 2
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and f"{scene}: master.{key}: b (Early.fmu) is an FMI 3.0 FMU" in lines[0], p.stderr


def _description_only(tmp_path, name, body, version="3.0", cs=True):
    xml = f"""<?xml version="1.0"?>
<fmiModelDescription fmiVersion="{version}" modelName="{name}" instantiationToken="x" guid="x">
  {'<CoSimulation modelIdentifier="M"/>' if cs else '<ScheduledExecution modelIdentifier="M"/>'}
  <ModelVariables>{body}</ModelVariables>
  <ModelStructure/>
</fmiModelDescription>"""
    path = tmp_path / f"{name}.fmu"
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("modelDescription.xml", xml)
    return path


@pytest.mark.parametrize("name, body, cs, feature", [
    # Clocks (engine/clocks.py) need Event Mode in Co-Simulation, a priority in Scheduled Execution.
    ("Ticker", '<Clock name="c" valueReference="1" causality="input" intervalVariability="triggered"/>',
     True, "it has clocks but no Event Mode"),
    ("Scheduled", '<Clock name="c" valueReference="1" causality="input" intervalVariability="triggered"/>',
     False, "clock c: an input clock of Scheduled Execution needs a priority"),
    ("Arrays", '<Binary name="a" valueReference="1" causality="output"><Dimension start="3"/></Binary>',
     True, "has an array of Binary values (a)"),
])
def test_unsupported_fmi3_features_are_refused_in_one_line(tmp_path, name, body, cs, feature):
    path = _description_only(tmp_path, name, body, cs=cs)
    with pytest.raises(FmuError, match=rf"{name}:? {feature.replace('(', '[(]').replace(')', '[)]')}"):
        read_fmu(path, need_binary=False)
    scene = tmp_path / "s.toml"
    scene.write_text(f'[scene]\ntitle = "t"\n[components.a]\nfmu = "{path.name}"\n[experiment]\nstop = 1\n')
    p = subprocess.run([sys.executable, "-m", "clockwork", "validate", str(scene)], capture_output=True, text=True)
    assert p.returncode == 2
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "components.a.fmu" in lines[0] and feature in lines[0], p.stderr


def test_fmi_version_picks_the_build_of_a_model_name(fmus, tmp_path, monkeypatch):
    """master.fmi_version = 3 looks model names up in <FMU dir>/fmi3/; a path
    is whatever it is; --set flips it; other values are bad input."""
    d = tmp_path / "fmus"
    (d / "fmi3").mkdir(parents=True)
    (d / "fmi3" / "Bouncer.fmu").write_bytes(fmus["early"].read_bytes())
    scene = tmp_path / "s.toml"
    scene.write_text('[scene]\ntitle = "t"\n[components.b]\nfmu = "Bouncer"\n[experiment]\nstop = 1\n'
                     '[master]\nstep = 0.1\nfmi_version = 3\n[record]\noutputs = ["b.x"]\n')
    env = {"CLOCKWORK_FMU_DIR": str(d), "CLOCKWORK_CACHE": "off"}

    def cli(*args):
        import os
        return subprocess.run([sys.executable, "-m", "clockwork", *args], capture_output=True, text=True,
                              env={**os.environ, **env})

    p = cli("validate", str(scene))
    assert p.returncode == 0, p.stderr
    p = cli("validate", str(scene), "--set", "master.fmi_version=2")
    assert p.returncode == 2 and f"{d}/Bouncer.fmu" in p.stderr and len(p.stderr.splitlines()) == 1
    p = cli("validate", str(scene), "--set", "master.fmi_version=4")
    assert p.returncode == 2 and "master.fmi_version" in p.stderr and "expected 2 or 3" in p.stderr
    out = tmp_path / "out"
    p = cli("run", str(scene), "--out", str(out), "--no-progress")
    assert p.returncode == 0, p.stderr
    series = (out / "timeseries.csv").read_text().splitlines()
    assert series[-1].startswith("1") and abs(float(series[-1].split(",")[1]) - 1.0) < 1e-12


def test_an_fmu_ending_the_run_is_a_result(fmus, tmp_path):
    import os
    scene = tmp_path / "s.toml"
    scene.write_text(f'[scene]\ntitle = "t"\n[components.b]\nfmu = "{fmus["early"]}"\n'
                     'parameters = { n_stop = 3 }\n[experiment]\nstop = 5\n[master]\nstep = 0.1\n'
                     '[record]\noutputs = ["b.x"]\n')
    out = tmp_path / "out"
    p = subprocess.run([sys.executable, "-m", "clockwork", "run", str(scene), "--out", str(out), "--no-progress"],
                       capture_output=True, text=True, env={**os.environ, "CLOCKWORK_CACHE": "off"})
    assert p.returncode == 0, p.stderr
    summary = json.loads((out / "summary.json").read_text())
    text = json.dumps(summary)
    assert '"ended"' in text and "terminateSimulation" in text
    ended = summary["result"]["ended"]
    assert summary["result"]["t_end_s"] == 0.75 and ended["instance"] == "b"
    assert ended["last_point_s"] == 0.75 and abs(ended["time_s"] - 0.75) < 1e-12
    assert (out / "timeseries.csv").read_text().splitlines()[-1].startswith("0.75,")


FMI3_DIR = FMU_DIR / "fmi3"
needs_fmi3_build = pytest.mark.skipif(
    not (FMI3_DIR / "Pendulum.fmu").is_file(),
    reason=f"the FMI 3.0 builds of the bundled FMUs ({FMI3_DIR}) are not built yet")


@needs_fmi3_build
@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("early_return", [True, False])
def test_bundled_clock_fmi3_matches_fmi2(engine, early_return):
    """The grasshopper clock on the FMI 3.0 build gives the FMI 2.0 build's
    bits in both engines, with the same switches located. With early return
    the Pendulum stops at each tick and turning point and then goes on with
    the internal step it stood in (the same steps as without early return);
    without it, it handles them inside fmi3DoStep as the FMI 2.0 build does."""
    def go(version):
        with System({"pendulum": ("Pendulum", {"Q": 1000.0, "phi_start": 0.1}),
                     "escapement": ("GrasshopperEscapement", {})},
                    ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w",
                     "escapement.tau -> pendulum.tau_escapement"],
                    MasterSettings(step=0.05, engine=engine, fmi_version=version, early_return=early_return),
                    record={"pendulum": ["phi", "tick_time"]}) as s:
            rec = Recorder(s.master, [("pendulum", "phi")], ticks_of="pendulum")
            rec.start()
            s.master.run_until(20.0, rec)
            early = s.instances["pendulum"].events.early_returns if version == 3 else 0
            return rec.columns, rec.ticks, s.master.stats.events, early
    (c2, t2, e2, _), (c3, t3, e3, early) = go(2), go(3)
    assert len(t2) == len(t3) > 5 and e2 == e3 >= 2 * len(t3)  # two switches per tick
    assert max(abs(a - b) for a, b in zip(t2, t3)) < 1e-10
    assert max(abs(a - b) for a, b in zip(c2["pendulum.phi"], c3["pendulum.phi"])) < 1e-12
    if early_return:
        assert early >= 2 * len(t3)  # at least each tick and turning point
    else:
        assert early == 0
    assert (c2, t2) == (c3, t3)


@needs_fmi3_build
@pytest.mark.parametrize("early_return", [True, False])
def test_event_prediction_on_fmi3_lands_the_switches_without_rollback(early_return):
    """Event prediction takes the indicator's source derivatives from
    fmi3GetOutputDerivatives as from fmi2GetRealOutputDerivatives: on the
    FMI 3.0 build the escapement's switches are landed on by predicted
    steps without a rollback (with prediction off, by rollback), both
    engines give the same statistics and bits, and the ticks agree with
    the rollback run's within the location tolerance."""
    def go(engine, prediction):
        with System({"pendulum": ("Pendulum", {"Q": 1000.0, "phi_start": 0.1}),
                     "escapement": ("GrasshopperEscapement", {})},
                    ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w",
                     "escapement.tau -> pendulum.tau_escapement"],
                    MasterSettings(step=0.05, engine=engine, fmi_version=3, early_return=early_return,
                                   event_prediction=prediction),
                    record={"pendulum": ["phi", "tick_time"]}) as s:
            assert s.master.engine == engine
            rec = Recorder(s.master, [("pendulum", "phi")], ticks_of="pendulum")
            rec.start()
            s.master.run_until(20.0, rec)
            return rec.columns, rec.ticks, vars(s.master.stats).copy()
    predicted = {e: go(e, True) for e in ENGINES}
    assert predicted["python"] == predicted["compiled"]
    _, ticks, stats = predicted["compiled"]
    _, ticks_rb, stats_rb = go("compiled", False)
    assert stats["predicted_landings"] >= 2 * len(ticks) > 10 and stats["rollbacks"] == 0
    assert stats_rb["rollbacks"] > 0 and stats_rb["predicted_landings"] == 0
    assert stats["events"] == stats_rb["events"] and len(ticks) == len(ticks_rb)
    assert max(abs(a - b) for a, b in zip(ticks, ticks_rb)) < 1e-9


@needs_fmi3_build
def test_export_suite_writes_fmi3_cases(tmp_path, monkeypatch):
    """export-suite --fmi-version 3 writes the single-FMU case with the FMI
    3.0 build, in the cross-check tree's FMI 3.0 branch."""
    from clockwork import __version__, cli
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))
    out = tmp_path / "kit"
    assert cli.main(["export-suite", str(out), "--only", "Pendulum", "--fmi-version", "3"]) == 0
    fmu = out / "fmus" / "3.0" / "cs" / "x86_64-linux" / "clockwork" / __version__ / "Pendulum" / "Pendulum.fmu"
    with zipfile.ZipFile(fmu) as z:
        assert b'fmiVersion="3.0"' in z.read("modelDescription.xml")
        assert "extra/org.fmi-standard.fmi-ls-ref/Pendulum_ref.csv" in z.namelist()


@needs_fmi3_build
@pytest.mark.parametrize("engine", ENGINES)
def test_bundled_mixed_scene_fmi3_pendulum_fmi2_escapement(engine, tmp_path):
    """A scene mixing the FMI 3.0 Pendulum (a path) with the FMI 2.0
    escapement (a model name) runs like the all-FMI 2.0 scene: bit for bit
    without early return, to 1e-12 with it; and --set master.fmi_version=3
    flips the escapement's build too."""
    import os
    from cwtest import CLOCK_SCENE
    base = CLOCK_SCENE.format(stop=3.0, sweep="")
    mixed = base.replace('fmu = "Pendulum"', f'fmu = "{FMI3_DIR / "Pendulum.fmu"}"')
    assert mixed != base
    outs = {}
    for label, text, sets in (("fmi2", base, []), ("mixed", mixed, ["master.early_return=false"]),
                              ("mixed_er", mixed, []), ("fmi3", base, ["master.fmi_version=3"])):
        scene = tmp_path / f"{label}.toml"
        scene.write_text(text)
        args = [sys.executable, "-m", "clockwork", "run", str(scene), "--out", str(tmp_path / label), "--no-progress",
                "--set", f"master.engine={engine}"]
        for s in sets:
            args += ["--set", s]
        p = subprocess.run(args, capture_output=True, text=True, env={**os.environ, "CLOCKWORK_CACHE": "off"})
        assert p.returncode == 0, p.stderr
        outs[label] = ((tmp_path / label / "timeseries.csv").read_text(),
                       json.loads((tmp_path / label / "summary.json").read_text()))
    assert outs["mixed"][0] == outs["fmi2"][0]
    assert outs["fmi3"][1]["settings"]["master"]["fmi_version"] == 3
    rows = [[float(x) for x in line.split(",")] for line in outs["mixed_er"][0].splitlines()[1:]]
    ref = [[float(x) for x in line.split(",")] for line in outs["fmi2"][0].splitlines()[1:]]
    assert len(rows) == len(ref)
    assert max(abs(a - b) for r, q in zip(rows, ref) for a, b in zip(r, q)) < 1e-12
    assert outs["fmi3"][0].splitlines()[0] == outs["fmi2"][0].splitlines()[0]
    assert len(outs["fmi3"][0].splitlines()) == len(outs["fmi2"][0].splitlines())


def _scene_stems():
    from clockwork.paths import scenarios_dir
    return sorted(p.stem for p in scenarios_dir().glob("*.toml"))


@needs_fmi3_build
def test_every_bundled_scene_runs_on_the_fmi3_build():
    """Each scene loads with master.fmi_version = 3 (its model names then name
    fmus/fmi3/ files) and its system runs a few communication steps, those
    that hand the Pendulum its inputs as polynomials (extrapolation, strong
    coupling) included: they reach it by intermediate update."""
    from clockwork.analyses.context import build_system
    from clockwork.run.catalog import load_scene
    from clockwork.paths import scenarios_dir
    polynomial = 0
    for stem in _scene_stems():
        scene = load_scene(scenarios_dir() / f"{stem}.toml", ["master.fmi_version=3"])
        for c in scene.components.values():
            assert c.fmu_path.parent == FMI3_DIR and c.model_description.fmiVersion == "3.0", stem
        m = scene.master
        point = scene.sweep.points()[0] if scene.sweep else {}
        with build_system(scene, point) as s:
            start = s.master.t
            s.master.run_until(start + 20 * m.step)
            assert s.master.t > start, stem
            if m.extrapolation or m.iterations > 0:
                polynomial += 1
                assert any(getattr(i, "intermediate_update", False) for i in s.instances.values()), stem
    assert polynomial >= 8  # the scenes an FMI 3.0 build without intermediate update refused


@needs_fmi3_build
@pytest.mark.parametrize("stem", ["ziemkiewicz_fig4a", "hoyng_fig4", "ziemkiewicz_fig7a"])
def test_bundled_scene_point_same_bits_on_both_builds_without_early_return(stem):
    """A sweep point (shooting), Hoyng's averaged comparison and a kicked
    clock: the FMI 3.0 build without early return gives the FMI 2.0 bits."""
    from clockwork.analyses.registry import run_analysis
    from clockwork.run.catalog import load_scene
    from clockwork.paths import scenarios_dir
    out = []
    for sets in ([], ["master.fmi_version=3", "master.early_return=false"]):
        scene = load_scene(scenarios_dir() / f"{stem}.toml", sets)
        point = scene.sweep.points()[0] if scene.sweep else {}
        res = run_analysis(scene, point)
        res["result"] = {k: v for k, v in res["result"].items() if "wall" not in k and "cpu" not in k}
        out.append(json.dumps(res, sort_keys=True, default=str))
    assert out[0] == out[1]


@needs_fmi3_build
@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("key, value", [("extrapolation", 1), ("extrapolation", 2), ("iterations", 2)])
def test_polynomial_inputs_reach_fmi3_by_intermediate_update(engine, key, value):
    """Extrapolated inputs and strong coupling's lines between iterates
    reach the FMI 3.0 Pendulum through intermediate update: at each RK
    stage its fmi3DoStep calls back and the master sets the input
    polynomial's value there, with the FMI 2.0 FMU's arithmetic, so that
    without early return the two builds give the same bits."""
    def go(version):
        with System({"pendulum": ("Pendulum", {"Q": 1000.0, "phi_start": 0.1}),
                     "escapement": ("GrasshopperEscapement", {}), "drag": ("Drag", {"c1": 5e-4, "c2": 5e-3})},
                    ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w",
                     "escapement.tau -> pendulum.tau_escapement", "pendulum.w -> drag.w",
                     "drag.tau -> pendulum.tau_drag"],
                    MasterSettings(step=0.05, engine=engine, fmi_version=version, early_return=False,
                                   **{key: value}),
                    record={"pendulum": ["phi", "tick_time"]}) as s:
            rec = Recorder(s.master, [("pendulum", "phi"), ("pendulum", "w")], ticks_of="pendulum")
            rec.start()
            s.master.run_until(6.0, rec)
            inst = s.instances["pendulum"]
            calls = inst.events.iu_calls if version == 3 else 0
            return rec.columns, rec.ticks, calls, getattr(inst, "intermediate_update", None)
    (c2, t2, _, _), (c3, t3, calls, on) = go(2), go(3)
    assert on is True
    assert calls > 6.0 / 0.05  # at least one set per communication step (many stages each)
    assert len(t2) >= 3 and (c2, t2) == (c3, t3)


@pytest.mark.parametrize("engine", ENGINES)
def test_an_fmu_that_refuses_the_event_mode_it_declares_runs_without_it(fmus, engine, capsys):
    """hasEventMode declared, eventModeUsed refused by the binary (as
    Reference-FMUs' Roberts): instantiated again without Event Mode, as
    fmpy instantiates; the same bits as the FMU that declares none, and a
    note on stderr naming the instance and the FMU's message."""
    refusing = run(fmus["refusing"], {"v0": 0.7, "period": 0.0}, 6.0, 0.5, engine)
    inside = run(fmus["inside"], {"v0": 0.7, "period": 0.0}, 6.0, 0.5, engine)
    assert refusing[0] == inside[0]
    assert refusing[0]["b.bounces"][-1] == 4.0
    err = capsys.readouterr().err
    assert err.count("warning:") == 1 and "b declares hasEventMode but refused eventModeUsed" in err, err
    assert "Event Mode is not supported." in err, err
