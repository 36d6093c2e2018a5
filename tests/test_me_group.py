"""Connected Model Exchange FMUs as one group (engine/me_group.py).

A bouncing ball whose floor is another Model Exchange FMU's output (a lag
that decays) bounces at the analytic times whatever the communication
step: the group evaluates the connection at every stage of its one
integrator and locates the ball's indicator with the floor moving.
Stepped apart (master.me_groups = false) the floor is sampled at
communication points and the bounce is late by far more than the
tolerance. A chain of two lags equals its closed form to the integrator's
tolerance at any step. FMI 2.0 and 3.0 members, and a mix. A ball whose
bounce another FMU's logic commands through a Boolean bounces at the
floor whatever the step. The compiled engine runs a group (cw_me_group.c)
with the Python engine's bits.
"""

from __future__ import annotations

import math

import pytest

from clockwork.engine import MasterSettings, System
from clockwork.engine.recording import Recorder
from clockwork.errors import SceneError
from cwtest import FMU_DIR, test_fmu

VERSIONS = ("", "fmi3/")
G, E, H0 = 9.81, 0.8, 1.0  # MeFloorBall's gravity, restitution, start height
Y0, T_FLOOR = 0.3, 0.5  # the floor: MeLag with u = 0, y(0) = Y0, time constant T_FLOOR


def me(name: str, version: str = "") -> str:
    return str(test_fmu(version + name))


def run(components, links, stop, step, record, **settings):
    settings.setdefault("engine", "python")
    settings.setdefault("tolerance", 1e-10)
    with System(components, list(links), MasterSettings(step=step, **settings), record=record) as s:
        rec = Recorder(s.master, [(i, v) for i, names in record.items() for v in names])
        rec.start()
        s.master.run_until(stop, rec)
        return rec.columns, vars(s.master.stats).copy(), s.master


def floor(t: float) -> float:
    return Y0 * math.exp(-t / T_FLOOR)


def _root(f, a: float, b: float) -> float:
    """f(a) > 0 >= f(b): bisection to the resolution of time."""
    for _ in range(200):
        m = 0.5 * (a + b)
        if m in (a, b):
            break
        if f(m) > 0:
            a = m
        else:
            b = m
    return b


def bounce_times(stop: float) -> list[float]:
    """The ball's impacts on the moving floor until `stop`, s (its flight in closed form)."""
    times = []
    t0, h0, v0 = 0.0, H0, 0.0
    while True:
        gap = lambda t: h0 + v0 * (t - t0) - 0.5 * G * (t - t0) ** 2 - floor(t)  # noqa: E731
        a = t0 + 1e-6
        b = a
        while gap(b) > 0:
            a, b = b, b + 1e-3
        t = _root(gap, a, b)
        if t > stop:
            return times
        times.append(t)
        t0, h0, v0 = t, floor(t), -E * (v0 - G * (t - t0))


BALL_ON_FLOOR = ["floor.y -> ball.floor"]


def ball_on_floor(version_ball="", version_floor=""):
    return {"ball": (me("MeFloorBall", version_ball), {}),
            "floor": (me("MeLag", version_floor), {"y0": Y0, "T": T_FLOOR})}


@pytest.mark.parametrize("versions", [("", ""), ("fmi3/", "fmi3/"), ("fmi3/", "")])
@pytest.mark.parametrize("step", [1.0, 1e-3])
def test_a_ball_on_a_model_exchange_floor_bounces_at_the_analytic_times(versions, step):
    stop = 2.0
    cols, stats, master = run(ball_on_floor(*versions), BALL_ON_FLOOR, stop, step,
                              {"ball": ["t_bounce", "bounces", "h"], "floor": ["y"]})
    expected = bounce_times(stop)
    assert len(expected) == 3
    assert cols["ball.bounces"][-1] == len(expected)
    assert abs(cols["ball.t_bounce"][-1] - expected[-1]) < 1e-7, (cols["ball.t_bounce"][-1], expected[-1])
    assert abs(cols["floor.y"][-1] - floor(stop)) < 1e-8
    group = stats["model_exchange"]["ball+floor"]
    assert group["members"] == ["ball", "floor"] and group["state_events"] == 3
    # every recorded time: the first bounce, as each step saw it
    first = expected[0]
    for t, tb in zip(cols["time"], cols["ball.t_bounce"]):
        if first < t < expected[1]:
            assert abs(tb - first) < 1e-7


@pytest.mark.parametrize("step", [1.0, 1e-3])
def test_stepped_apart_the_sampled_floor_makes_the_bounce_late(step):
    """The check above fails without the group: the floor is seen at communication points only."""
    cols, _, _ = run(ball_on_floor(), BALL_ON_FLOOR, 2.0, step, {"ball": ["t_bounce", "bounces"]},
                     me_groups=False)
    assert abs(cols["ball.t_bounce"][-1] - bounce_times(2.0)[-1]) > 1e-6


def lags(version_a="", version_b=""):
    return {"a": (me("MeLag", version_a), {"u": 1.0, "T": 0.5}),
            "b": (me("MeLag", version_b), {"k": 2.0, "T": 0.2})}


def chain_of_states(t: float) -> float:
    """b.y when a.y (a lag of 1 with T1) drives b (gain 2, T2)."""
    t1, t2 = 0.5, 0.2
    return 2.0 * (1.0 - (t1 * math.exp(-t / t1) - t2 * math.exp(-t / t2)) / (t1 - t2))


def chain_through_feedthrough(t: float) -> float:
    """b.y when a.e = 1 - a.y (direct feedthrough of a's input) drives b."""
    t1, t2 = 0.5, 0.2
    return 2.0 * t1 / (t1 - t2) * (math.exp(-t / t1) - math.exp(-t / t2))


@pytest.mark.parametrize("versions", [("", ""), ("fmi3/", "fmi3/"), ("", "fmi3/")])
@pytest.mark.parametrize("step", [1.0, 0.01])
@pytest.mark.parametrize("link,closed", [("a.y -> b.u", chain_of_states), ("a.e -> b.u", chain_through_feedthrough)])
def test_a_chain_of_two_lags_equals_its_closed_form_at_any_step(versions, step, link, closed):
    cols, _, _ = run(lags(*versions), [link], 3.0, step, {"b": ["y"]})
    err = max(abs(y - closed(t)) for t, y in zip(cols["time"], cols["b.y"]))
    assert err < 1e-7, err
    assert len(cols["time"]) == round(3.0 / step) + 1


def test_stepped_apart_a_coarse_step_misses_the_closed_form():
    cols, _, _ = run(lags(), ["a.e -> b.u"], 3.0, 1.0, {"b": ["y"]}, me_groups=False)
    assert max(abs(y - chain_through_feedthrough(t)) for t, y in zip(cols["time"], cols["b.y"])) > 1e-3


def test_a_group_is_one_instance_to_the_rest_of_the_scene():
    """Outputs of members read by name; a Co-Simulation-facing link into a member's free input."""
    comps = dict(lags(), c=(me("MeLag"), {"T": 0.1}))
    with System(comps, ["a.y -> b.u", "b.y -> c.u"], MasterSettings(step=0.1, engine="python"),
                record={"b": ["y"]}) as s:
        assert set(s.master.instances) == {"a+b+c"}
        s.master.run_until(1.0)
        assert abs(s.output("b", "y") - chain_of_states(1.0)) < 1e-7
        assert abs(s.value("a", "y") - (1 - math.exp(-1.0 / 0.5))) < 1e-8


def test_an_algebraic_loop_inside_a_group_is_refused_in_one_line():
    with pytest.raises(SceneError) as e:
        System(lags(), ["a.e -> b.u", "b.e -> a.u"], MasterSettings(step=0.1, engine="python"))
    assert "algebraic loop inside it" in str(e.value) and "\n" not in str(e.value)
    assert "master.me_groups = false" in str(e.value)


# -- a ball and the logic that bounces it, joined by a Boolean ------------------------------------------------

LOGIC = ["ball.h -> logic.h", "ball.v -> logic.v", "logic.hit -> ball.hit"]


def ball_and_logic(version_ball="", version_logic=""):
    return {"ball": (me("MeLogicBall", version_ball), {}), "logic": (me("MeBounceLogic", version_logic), {})}


def floor_bounces(stop: float) -> list[float]:
    """The impacts of MeLogicBall on a floor at 0 until `stop`, s (closed form)."""
    times, t, v = [], math.sqrt(2.0 * H0 / G), math.sqrt(2.0 * G * H0)
    while t <= stop:
        times.append(t)
        v *= E
        t += 2.0 * v / G
    return times


@pytest.mark.parametrize("engine", ["python", "compiled"])
@pytest.mark.parametrize("versions", [("", ""), ("fmi3/", "")])
@pytest.mark.parametrize("step", [1.0, 0.01])
def test_a_ball_bounces_where_the_logic_says_whatever_the_step(engine, versions, step):
    """The logic's event (its indicator on the ball's height, evaluated at
    every stage) sets the Boolean, the ball reverses in the same event
    iteration, and the logic's output falls back once the ball rises."""
    stop = 2.0
    cols, stats, master = run(ball_and_logic(*versions), LOGIC, stop, step,
                              {"ball": ["t_bounce", "bounces", "h"], "logic": ["hit"]}, engine=engine)
    assert master.engine == engine
    expected = floor_bounces(stop)
    assert len(expected) == 3
    assert cols["ball.bounces"][-1] == len(expected)
    assert abs(cols["ball.t_bounce"][-1] - expected[-1]) < 1e-7, (cols["ball.t_bounce"][-1], expected[-1])
    assert min(cols["ball.h"]) > -1e-9
    assert not any(cols["logic.hit"])  # true only inside the events


def test_stepped_apart_the_ball_falls_through_the_floor():
    cols, _, _ = run(ball_and_logic(), LOGIC, 2.0, 0.01, {"ball": ["h", "bounces"]}, me_groups=False)
    assert min(cols["ball.h"]) < -1e-3


# Each case: (components, links, record, settings), made when the test runs (the FMUs are built by then).
CASES = {
    "floor": lambda: (ball_on_floor(), BALL_ON_FLOOR,
                      {"ball": ["t_bounce", "bounces", "h", "v"], "floor": ["y"]}, {}),
    "floor_fmi3_mix": lambda: (ball_on_floor("fmi3/", ""), BALL_ON_FLOOR, {"ball": ["t_bounce", "h"], "floor": ["y"]},
                               {}),
    "lags": lambda: (lags(), ["a.e -> b.u"], {"b": ["y"], "a": ["e"]}, {}),
    "timer": lambda: ({"timer": (me("MeTimer"), {}), "lag": (me("MeLag", "fmi3/"), {"T": 0.2})},
                      ["timer.x -> lag.u"], {"lag": ["y"], "timer": ["turns", "level"]}, {}),
    "logic": lambda: (ball_and_logic(), LOGIC, {"ball": ["t_bounce", "bounces", "h"], "logic": ["hit"]}, {}),
    "logic_fmi3": lambda: (ball_and_logic("fmi3/", "fmi3/"), LOGIC, {"ball": ["t_bounce", "h"]}, {}),
    "floor_fmi1": lambda: (ball_on_floor("fmi1me/", "fmi1me/"), BALL_ON_FLOOR, {"ball": ["t_bounce", "h"], "floor": ["y"]},
                           {}),
    "dp54": lambda: (ball_on_floor(), BALL_ON_FLOOR, {"ball": ["t_bounce", "h"]}, {"me_solver": "dp54"}),
    "cvode": lambda: (ball_and_logic(), LOGIC, {"ball": ["t_bounce", "h"]}, {"me_solver": "cvode"}),
    # a group and a Co-Simulation FMU coupled both ways (the group is one instance to the master)
    "clock": lambda: ({"pendulum": (me("MePendulum"), {}), "lag": (me("MeLag"), {"T": 0.1}),
                       "escapement": (str(FMU_DIR / "GrasshopperEscapement.fmu"), {"torque": 0.004, "phi_r": 0.035})},
                      ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w",
                       "escapement.tau -> pendulum.tau_escapement", "pendulum.phi -> lag.u"],
                      {"pendulum": ["phi", "tick_time"], "lag": ["y"]}, {}),
}


@pytest.mark.parametrize("step", [0.3, 0.01])
@pytest.mark.parametrize("case", list(CASES))
def test_both_engines_give_the_same_bits(case, step):
    components, links, record, extra = CASES[case]()
    out = {engine: run(components, links, 2.0, step, record, engine=engine, **extra)
           for engine in ("python", "compiled")}
    assert out["compiled"][2].engine == "compiled"
    assert out["python"][0] == out["compiled"][0]
    assert out["python"][1] == out["compiled"][1]


def test_a_connection_the_core_does_not_evaluate_hands_the_group_to_python_in_one_line():
    """An Integer output into a Real input (converted by the Python engine's typed calls)."""
    links = BALL_ON_FLOOR + ["ball.bounces -> floor.u"]
    cols, _, master = run(ball_on_floor(), links, 1.0, 0.5, {"floor": ["y"]}, engine="auto")
    assert master.engine == "python"
    assert master.engine_reason == ("the compiled core evaluates a Model Exchange group's Real, Integer and Boolean "
                                    "connections only (ball+floor: ball.bounces -> floor.u): the Python engine runs it")
    with pytest.raises(SceneError, match="master.engine = 'compiled': the compiled core evaluates") as e:
        run(ball_on_floor(), links, 1.0, 0.5, {"floor": ["y"]}, engine="compiled")
    assert "\n" not in str(e.value)


def test_the_compiled_engine_runs_a_group_and_says_no_reason():
    """Before, the compiled engine refused a group (and "auto" fell back to Python)."""
    _, _, master = run(ball_on_floor(), BALL_ON_FLOOR, 1.0, 0.5, {"ball": ["t_bounce"]}, engine="compiled")
    assert master.engine == "compiled"
    _, _, master = run(ball_on_floor(), BALL_ON_FLOOR, 1.0, 0.5, {"ball": ["t_bounce"]}, engine="auto")
    assert master.engine == "compiled" and master.engine_reason is None


def _scene(tmp_path, extra=""):
    scene = tmp_path / "floor.toml"
    scene.write_text(f"""
connections = ["floor.y -> ball.floor"]

[scene]
title = "a ball on a Model Exchange floor"

[components.ball]
fmu = "{me('MeFloorBall')}"

[components.floor]
fmu = "{me('MeLag')}"
parameters = {{ y0 = {Y0}, T = {T_FLOOR} }}

[experiment]
stop = "1 s"

[master]
step = "1 s"
tolerance = 1e-10
{extra}

[record]
outputs = ["ball.t_bounce", "floor.y"]

[analysis]
kind = "time_series"
""")
    return scene


@pytest.mark.parametrize("groups", [True, False])
def test_a_scene_groups_its_model_exchange_fmus_unless_told_not_to(tmp_path, capsys, groups):
    import json

    from clockwork.results.load import load
    from cwtest import run_cli

    scene = _scene(tmp_path, "" if groups else "me_groups = false")
    rc, _, err = run_cli(capsys, ["run", scene, "--out", tmp_path / "out", "--no-progress"])
    assert rc == 0, err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    series = load(tmp_path / "out").series
    assert {"time", "ball.t_bounce", "floor.y"} <= set(series.dtype.names)
    late = abs(float(series["ball.t_bounce"][-1]) - bounce_times(1.0)[0])
    if groups:
        assert "ball+floor" in summary["statistics"]["model_exchange"]
        assert summary["result"]["engine"] == "compiled" and "engine_reason" not in summary["result"]
        assert late < 1e-7
    else:
        assert set(summary["statistics"]["model_exchange"]) == {"ball", "floor"}
        assert late > 1e-3


@pytest.mark.parametrize("engine", ["python", "compiled"])
def test_a_restarted_group_gives_the_same_bits(engine):
    record = {"ball": ["h"], "floor": ["y"]}
    with System(ball_on_floor(), BALL_ON_FLOOR, MasterSettings(step=0.1, engine=engine, tolerance=1e-10),
                record=record) as s:
        seen = []
        for _ in range(2):
            rec = Recorder(s.master, [(i, v) for i, names in record.items() for v in names])
            rec.start()
            s.master.run_until(1.0, rec)
            seen.append(rec.columns)
            s.restart({"floor": {"y0": Y0, "T": T_FLOOR}})
        assert seen[0] == seen[1]
        assert abs(seen[0]["floor.y"][-1] - floor(1.0)) < 1e-8


def test_time_and_step_events_of_a_member_drive_the_group_whatever_the_step():
    """MeTimer's level switches at time events and its angle wraps at step
    events (fmi2CompletedIntegratorStep); a lag (FMI 3.0) follows its x.
    The group stops at every member's time event: the lag's value does not
    depend on the communication step, where stepped apart it does."""
    def lag_at_3(step, **settings):
        cols, stats, _ = run({"timer": (me("MeTimer"), {}), "lag": (me("MeLag", "fmi3/"), {"T": 0.2})},
                             ["timer.x -> lag.u"], 3.0, step, {"lag": ["y"], "timer": ["turns"]}, **settings)
        return cols["lag.y"][-1], cols["timer.turns"][-1], stats["model_exchange"]

    reference, turns, stats = lag_at_3(0.01)
    assert turns == 2 and stats["timer+lag"]["step_events"] == 2 and stats["timer+lag"]["time_events"] >= 3
    for step in (1.0, 0.37):
        assert abs(lag_at_3(step)[0] - reference) < 1e-8
    assert abs(lag_at_3(1.0, me_groups=False)[0] - reference) > 1e-3


@pytest.mark.parametrize("solver", ["dp54", "dop853", "cvode"])
def test_every_integrator_integrates_a_group(solver):
    cols, stats, _ = run(ball_on_floor(), BALL_ON_FLOOR, 2.0, 1.0, {"ball": ["t_bounce", "bounces"]},
                         me_solver=solver)
    expected = bounce_times(2.0)
    assert cols["ball.bounces"][-1] == len(expected)
    assert abs(cols["ball.t_bounce"][-1] - expected[-1]) < 1e-7
    assert stats["model_exchange"]["ball+floor"]["solver"] == {"dp54": "DP5(4)", "dop853": "DOP853",
                                                               "cvode": "CVode BDF"}[solver]
