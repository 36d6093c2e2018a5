"""FMI 1.0 Model Exchange FMUs through the engine's Model Exchange wrapper
(fmi/me1.py), in both engines.

The FMUs are tests/me_models built behind the FMI 1.0 Model Exchange face
(me_fmi1.c, into build/test-fmus/fmi1me/): the same models as the FMI 2.0
builds, so that the same integrator with the same settings gives the same
bits through either face; fmpy's simulate_fmu of the FMI 1.0 build agrees
within the tolerances both integrate at.
"""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest

from clockwork.engine import MasterSettings, System
from clockwork.engine.recording import Recorder
from cwtest import fmu_file, run_cli, test_fmu

ENGINES = ("python", "compiled")


def me1(name: str) -> str:
    return str(test_fmu("fmi1me/" + name))


def me2(name: str) -> str:
    return str(test_fmu(name))


def run(components, stop=2.0, step=0.05, record=None, links=(), **settings):
    """(series, statistics, master.engine, ended) of a run on the grid."""
    settings.setdefault("engine", "python")
    with System(components, list(links), MasterSettings(step=step, **settings), record=record) as s:
        outputs = [(i, v) for i, names in record.items() for v in names]
        rec = Recorder(s.master, outputs)
        rec.start()
        s.master.run_until(stop, rec)
        return rec.columns, vars(s.master.stats).copy(), s.master.engine, s.master.ended


CASES = {
    "oscillator": ("MeOscillator", {}, ["x", "v"], {}),
    "ball": ("MeBall", {}, ["h", "v", "t_bounce"], {}),
    "ball_dop853": ("MeBall", {"e": 0.7}, ["h", "v", "bounces"], {"me_solver": "dop853"}),
    "ball_cvode": ("MeBall", {}, ["h", "v"], {"me_solver": "cvode"}),
    "timer": ("MeTimer", {}, ["x", "phase", "turns"], {}),  # time and step events
    "pendulum": ("MePendulum", {}, ["phi", "w"], {}),
    "stiff": ("MeStiff", {"lambda": 1e4}, ["y"], {}),  # "auto" hands it to CVode
}


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("case", list(CASES))
def test_the_fmi1_build_gives_the_fmi2_builds_bits(case, engine):
    name, parameters, outputs, extra = CASES[case]
    out = {}
    for version, path in (("1.0", me1(name)), ("2.0", me2(name))):
        out[version] = run({"m": (path, parameters)}, record={"m": outputs}, engine=engine, tolerance=1e-9,
                           **extra)
    (cols1, stats1, used1, _), (cols2, stats2, used2, _) = out["1.0"], out["2.0"]
    assert used1 == used2 == engine  # the compiled core runs FMI 1.0 Model Exchange itself
    assert cols1 == cols2
    assert stats1["model_exchange"] == stats2["model_exchange"]


@pytest.mark.parametrize("engine", ENGINES)
def test_an_fmi1_model_exchange_input_follows_a_co_simulation_fmu_as_the_fmi2_build(engine):
    """MeLag's continuous input from the clock's Pendulum (input polynomials, extrapolation)."""
    out = {}
    for version, path in (("1.0", me1("MeLag")), ("2.0", me2("MeLag"))):
        comps = {"p": (str(fmu_file("Pendulum")), {"phi_start": 0.2, "Q": 50.0}), "lag": (path, {})}
        out[version] = run(comps, links=["p.phi -> lag.u"], record={"lag": ["y", "e"]}, engine=engine,
                           tolerance=1e-9, extrapolation=2)
    assert out["1.0"][2] == out["2.0"][2] == engine
    assert out["1.0"][0] == out["2.0"][0]
    assert out["1.0"][1]["model_exchange"] == out["2.0"][1]["model_exchange"]


@pytest.mark.parametrize("engine", ENGINES)
def test_terminate_simulation_ends_an_fmi1_run_cleanly(engine):
    out = {v: run({"b": (p, {"n_stop": 3})}, stop=3.0, record={"b": ["h", "bounces"]}, engine=engine,
                  tolerance=1e-10) for v, p in (("1.0", me1("MeBall")), ("2.0", me2("MeBall")))}
    cols, _, _, ended = out["1.0"]
    assert ended is not None and cols["b.bounces"][-1] == 2  # the results end before the third bounce's step
    assert cols == out["2.0"][0] and ended.fmu_time == out["2.0"][3].fmu_time


def test_fmpy_agrees_with_the_fmi1_build():
    """fmpy's own FMI 1.0 Model Exchange loop (CVode, its event handling) on the same file."""
    from fmpy import simulate_fmu

    for name, outputs, stop in (("MeOscillator", ["x", "v"], 5.0), ("MeBall", ["h", "v"], 2.0)):
        path = me1(name)
        ref = simulate_fmu(path, stop_time=stop, output_interval=0.05, relative_tolerance=1e-10,
                           output=outputs, solver="CVode")
        cols, _, _, _ = run({"m": (path, {})}, stop=stop, record={"m": outputs}, tolerance=1e-10)
        t = np.array(cols["time"])
        for v in outputs:
            theirs = np.interp(t, ref["time"], ref[v])
            ours = np.array(cols["m." + v])
            # Away from the bounces (fmpy's output grid holds a pre- and a post-event point there).
            far = np.ones_like(t, dtype=bool)
            if name == "MeBall":
                bounces = ref["time"][1:][np.diff(ref["time"]) == 0]
                for tb in bounces:
                    far &= np.abs(t - tb) > 0.05
            assert far.sum() > len(t) // 2
            assert np.max(np.abs(ours[far] - theirs[far])) < 1e-6, (name, v)


def test_the_cli_runs_validates_and_describes_an_fmi1_model_exchange_fmu(tmp_path, capsys):
    fmu = me1("MeBall")
    rc, out, err = run_cli(capsys, ["info", fmu])
    assert rc == 0, err
    assert "1.0" in out and "Model Exchange" in out
    rc, out, err = run_cli(capsys, ["validate", fmu])
    assert rc == 0, err
    for engine in ENGINES:
        rc, _, err = run_cli(capsys, ["run", fmu, "--out", tmp_path / engine, "--no-progress",
                                      "--set", f"master.engine={engine}"])
        assert rc == 0, err
        summary = json.loads((tmp_path / engine / "summary.json").read_text())
        s = summary["statistics"]["model_exchange"]
        assert list(s.values())[0]["state_events"] >= 1


@pytest.mark.parametrize("engine", ENGINES)
def test_a_scene_runs_an_fmi1_model_exchange_component(tmp_path, capsys, engine):
    scene = tmp_path / "me1.toml"
    scene.write_text(f"""
[scene]
title = "an FMI 1.0 Model Exchange FMU"

[components.ball]
fmu = "{me1('MeBall')}"

[experiment]
stop = "1 s"

[master]
step = "0.05 s"
engine = "{engine}"

[record]
outputs = ["ball.h"]

[analysis]
kind = "time_series"
""")
    rc, _, err = run_cli(capsys, ["run", scene, "--out", tmp_path / "out", "--no-progress"])
    assert rc == 0, err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["statistics"]["model_exchange"]["ball"]["state_events"] == 1


def _rewrite(tmp_path, change, name="MeBall"):
    """A copy of the FMI 1.0 build of `name` with its modelDescription.xml changed by `change`."""
    src = test_fmu("fmi1me/" + name)
    out = tmp_path / f"{name}.fmu"
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(out, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == "modelDescription.xml":
                data = change(data.decode()).encode()
            zout.writestr(item, data)
    return out


@pytest.mark.parametrize("change, needle", [
    (lambda x: x.replace('numberOfContinuousStates="2"', 'numberOfContinuousStates="3"'),
     "numberOfContinuousStates = 3"),
    (lambda x: x.replace('name="der(h)"', 'name="dh"'), "der(<state>)"),
    (lambda x: x.replace('numberOfContinuousStates="2"', 'numberOfContinuousStates="two"'),
     "numberOfContinuousStates"),
])
def test_a_bad_fmi1_model_exchange_description_is_one_line(tmp_path, capsys, change, needle):
    fmu = _rewrite(tmp_path, change)
    for command in (["validate", fmu], ["run", fmu, "--out", tmp_path / "out", "--no-progress"]):
        rc, _, err = run_cli(capsys, command)
        assert rc == 2 and len(err.strip().splitlines()) == 1, err
        assert needle in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_a_negated_alias_is_refused_in_one_line(tmp_path, capsys):
    def negate(x):
        return x.replace('</ModelVariables>', '    <ScalarVariable name="minus_h" valueReference="1" '
                                              'alias="negatedAlias" causality="output"><Real/></ScalarVariable>\n'
                                              '  </ModelVariables>')
    fmu = _rewrite(tmp_path, negate)
    rc, _, err = run_cli(capsys, ["run", fmu, "--out", tmp_path / "out", "--no-progress"])
    assert rc == 2 and len(err.strip().splitlines()) == 1, err
    assert "negatedAlias" in err and "minus_h" in err


def test_rollback_is_refused_for_want_of_an_fmu_state():
    """FMI 1.0 has no FMU state: the wrapper says so, and the master's settings that roll back refuse it."""
    from clockwork.engine.instances import make_instance

    inst = make_instance("b", me1("MeBall"))
    assert not inst.can_get_set_state
    assert inst.named("getState") == "saving the FMU state (FMI 1.0 has none)"


@pytest.mark.parametrize("setting, needle", [("master.iterations=2", "iterating the coupling rolls every FMU back"),
                                             ("master.richardson=true", "step doubling rolls every FMU back")])
def test_settings_that_roll_back_are_refused_in_one_line(tmp_path, capsys, setting, needle):
    rc, _, err = run_cli(capsys, ["run", me1("MeBall"), "--out", tmp_path / "out", "--no-progress", "--set", setting])
    assert rc == 2 and len(err.strip().splitlines()) == 1, err
    assert "it is an FMI 1.0 FMU, which has no FMU state" in err and needle in err
    assert not (tmp_path / "out").exists()
