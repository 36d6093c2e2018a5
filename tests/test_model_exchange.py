"""Model Exchange FMUs, integrated by the master's own wrapper, in both engines.

The FMUs are tests/me_models (hand-written C against fmpy's headers, built
by CMake as FMI 2.0 into build/test-fmus/ and as FMI 3.0 into
build/test-fmus/fmi3/): a linear oscillator, a bouncing ball, time and
step events, a stiff problem, a lag with an input and the clock's
pendulum. Each is held against its closed form or a high-accuracy scipy
solution, and the compiled core against the Python reference, bit for bit.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from clockwork.engine import MasterSettings, System
from clockwork.engine import rk
from clockwork.engine.recording import Recorder
from clockwork.errors import SceneError, SimulationEnded
from cwtest import ROOT, fmu_file, run_cli, test_fmu

ENGINES = ("python", "compiled")
VERSIONS = ("", "fmi3/")


def me(name: str, version: str = "") -> str:
    return str(test_fmu(version + name))


def run(components, links=(), stop=1.0, step=0.01, record=None, interfaces=None, **settings):
    """(series, statistics, ended, master.engine) of a run on the grid."""
    settings.setdefault("engine", "python")
    record = record or {}
    with System(components, list(links), MasterSettings(step=step, **settings), record=record,
                interfaces=interfaces) as s:
        outputs = [(i, v) for i, names in record.items() for v in names]
        rec = Recorder(s.master, outputs)
        rec.start()
        s.master.run_until(stop, rec)
        return rec.columns, vars(s.master.stats).copy(), s.master.ended, s.master.engine


def me_stats(stats, name):
    return stats["model_exchange"][name]


# -- the integrators ------------------------------------------------------------


def oscillator(t, omega=2 * math.pi, zeta=0.05, x0=1.0, v0=0.0):
    wd = omega * math.sqrt(1 - zeta * zeta)
    return math.exp(-zeta * omega * t) * (x0 * math.cos(wd * t) + (v0 + zeta * omega * x0) / wd * math.sin(wd * t))


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("solver", ["dp54", "dop853", "cvode"])
def test_a_linear_ode_follows_its_closed_form(version, solver):
    cols, stats, _, _ = run({"o": (me("MeOscillator", version), {})}, stop=5.0, step=0.1,
                            record={"o": ["x"]}, tolerance=1e-10, me_solver=solver)
    err = max(abs(x - oscillator(t)) for t, x in zip(cols["time"], cols["o.x"]))
    # CVode's error runs ahead of its tolerance more than the pairs' do.
    assert err < (1e-7 if solver == "cvode" else 1e-8), err
    s = me_stats(stats, "o")
    assert s["solver"] == {"dp54": "DP5(4)", "dop853": "DOP853", "cvode": "CVode BDF"}[solver]
    assert s["tolerance"] == 1e-10 and s["steps"] >= 50 and s["rhs"] > s["steps"]


def test_the_tolerance_is_the_default_experiments_unless_the_master_sets_one():
    """MeBall declares 1e-8 in its DefaultExperiment; a tighter master.tolerance makes the error smaller."""
    _, stats, _, _ = run({"o": (me("MeBall"), {})}, stop=0.1)
    assert me_stats(stats, "o")["tolerance"] == 1e-8
    errors = {}
    for tol in (1e-5, 1e-9):
        cols, stats, _, _ = run({"o": (me("MeOscillator"), {})}, stop=5.0, step=0.5, record={"o": ["x"]},
                                tolerance=tol, me_solver="dp54")
        assert me_stats(stats, "o")["tolerance"] == tol
        errors[tol] = max(abs(x - oscillator(t)) for t, x in zip(cols["time"], cols["o.x"]))
    assert errors[1e-9] < 1e-3 * errors[1e-5], errors


def test_the_python_pairs_are_cw_rk_c_coefficient_for_coefficient():
    """rk.py's DOP853 tables are the literals of src_c/runtime/cw_rk.c (the twins compute the same bits)."""
    src = (ROOT / "src_c" / "runtime" / "cw_rk.c").read_text()

    def table(name):
        body = src[src.index(name):]
        body = body[body.index("{") + 1:body.index("};")]
        body = re.sub(r"\[\d+\]\s*=", "", body)
        return [eval(x) for x in re.findall(r"-?[\d.]+(?:e[+-]?\d+)?(?:\s*/\s*[\d.]+)?", body)]

    assert table("P8C[CW_RK_MAXSTAGES] =") == list(rk._C8)
    assert table("P8A[CW_RK_MAXSTAGES][CW_RK_MAXSTAGES - 1] =") == [a for row in rk._A8 for a in row]
    assert table("P8E5[12] =") == list(rk._E8)
    assert table("P8D[4][CW_RK_MAXSTAGES] =") == [d for row in rk._D8 for d in row]


def test_the_wrappers_constants_are_the_same_in_both_engines():
    """cw_me.c's limits and codes are me_step.py's (a difference shows only
    in rare runs: a fifth safeguard trial once changed no result but the
    location trials of a bouncing ball in its last bounces)."""
    from clockwork.engine import me_step

    src = (ROOT / "src_c" / "master" / "cw_me.c").read_text()
    defines = dict(re.findall(r"#define (\w+) (\d+)L?\b", src))
    for name in ("MAX_EVENT_ITERATIONS", "MAX_CVODE_STEPS", "MAX_TRIALS", "SAFEGUARD_TRIALS", "STIFF_STEPS",
                 "NONSTIFF_RESET"):
        assert int(defines[name]) == getattr(me_step, name), name
    assert f"me->method == DP54 ? {me_step.STIFF_LIMIT[me_step.DP54]} : {me_step.STIFF_LIMIT[me_step.DOP853]}" in src
    assert (f"enum {{ FAIL_SETTLE = {me_step.FAIL_SETTLE}, FAIL_TIME, FAIL_RK, FAIL_CVODE, FAIL_LOCATE, "
            f"FAIL_TIME_EVENTS }};") in src
    assert [me_step.FAIL_TIME, me_step.FAIL_RK, me_step.FAIL_CVODE, me_step.FAIL_LOCATE,
            me_step.FAIL_TIME_EVENTS] == list(range(me_step.FAIL_SETTLE + 1, me_step.FAIL_SETTLE + 6))


# -- events ----------------------------------------------------------------------


def bounce_times(n, h0=1.0, g=9.81, e=0.8):
    t = math.sqrt(2 * h0 / g)
    v = g * t
    times = [t]
    for _ in range(n - 1):
        v *= e
        t += 2 * v / g
        times.append(t)
    return times


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("engine", ENGINES)
def test_the_bouncing_ball_bounces_at_its_closed_form_times(version, engine):
    cols, stats, _, _ = run({"b": (me("MeBall", version), {})}, stop=3.0, step=0.01,
                            record={"b": ["h", "t_bounce"]}, engine=engine, tolerance=1e-10)
    seen = sorted(set(cols["b.t_bounce"]) - {0.0})
    expected = bounce_times(len(seen))
    assert len(seen) >= 6
    # Located to the event time tolerance (1e-10 s) past the crossing, with the integration's error.
    assert max(abs(a - b) for a, b in zip(seen, expected)) < 1e-8
    assert min(h for h in cols["b.h"]) > -1e-8  # never below the floor at a communication point
    s = me_stats(stats, "b")
    assert s["state_events"] == len(seen) and s["event_iterations"] > 0


@pytest.mark.parametrize("engine", ENGINES)
def test_an_indicator_that_starts_a_hair_above_zero_is_located_all_the_same(engine):
    """The Reference-FMUs' ball leaves each bounce from DBL_MIN: when the
    next landing falls inside the first integrator step, the secant from a
    bracket end at 2e-308 crawls; the locator bisects where four trials did
    not halve the bracket, and finds every bounce."""
    cols, stats, _, _ = run({"b": (me("MeBall"), {"lift": 2.2250738585072014e-308, "e": 0.7})}, stop=2.5, step=0.1,
                            record={"b": ["t_bounce"]}, engine=engine, tolerance=1e-10)
    expected = [t for t in bounce_times(40, e=0.7) if t < 2.5]
    assert len(expected) == 11 and expected[-1] - expected[-2] < 0.05  # the last flights: a fraction of a step
    assert me_stats(stats, "b")["state_events"] == len(expected)
    # Several bounces fall between two communication points: the last one of each is seen.
    seen = sorted(set(cols["b.t_bounce"]) - {0.0})
    assert max(min(abs(t - e) for e in expected) for t in seen) < 1e-8 and seen[-1] == pytest.approx(expected[-1])


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("engine", ENGINES)
def test_terminate_simulation_ends_the_run_cleanly(version, engine):
    cols, _, ended, _ = run({"b": (me("MeBall", version), {"n_stop": 3})}, stop=3.0, step=0.05,
                            record={"b": ["h"]}, engine=engine, tolerance=1e-10)
    assert isinstance(ended, SimulationEnded) and ended.instance == "b"
    assert abs(ended.fmu_time - bounce_times(3)[-1]) < 1e-8
    assert ended.time <= ended.fmu_time and cols["time"][-1] == ended.time


def timer(t, tau=0.3, A=1.0, period=0.7):
    """x of MeTimer: relaxes with tau towards a level that switches 0 <-> A at k * period."""
    x, level, t0 = 0.0, 0.0, 0.0
    k = 1
    while k * period <= t:
        x = level + (x - level) * math.exp(-(k * period - t0) / tau)
        t0 = k * period
        level = A if k % 2 else 0.0
        k += 1
    return level + (x - level) * math.exp(-(t - t0) / tau)


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("engine", ENGINES)
def test_time_events_switch_at_the_announced_times(version, engine):
    cols, stats, _, _ = run({"t": (me("MeTimer", version), {})}, stop=5.0, step=0.25,
                            record={"t": ["x", "switches"]}, engine=engine, tolerance=1e-10)
    err = max(abs(x - timer(t)) for t, x in zip(cols["time"], cols["t.x"]))
    assert err < 1e-8, err
    assert cols["t.switches"][-1] == int(5.0 / 0.7)
    # A switch that falls on a step event (the angle's) is handled there.
    assert me_stats(stats, "t")["time_events"] >= int(5.0 / 0.7) - 2


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("engine", ENGINES)
def test_step_events_wrap_the_angle(version, engine):
    """fmi2CompletedIntegratorStep asks for event mode after a step that
    left the angle above pi; there it drops by 2 pi: phase + 2 pi turns =
    omega t, and the angle never runs far past pi."""
    cols, stats, _, _ = run({"t": (me("MeTimer", version), {})}, stop=5.0, step=0.25,
                            record={"t": ["phase", "turns"]}, engine=engine, tolerance=1e-10)
    for t, phase, turns in zip(cols["time"], cols["t.phase"], cols["t.turns"]):
        assert abs(phase + 2 * math.pi * turns - 5.0 * t) < 1e-8
        assert -math.pi <= phase <= math.pi + 5.0 * 0.25
    assert cols["t.turns"][-1] == round(5.0 * 5.0 / (2 * math.pi))
    assert me_stats(stats, "t")["step_events"] == cols["t.turns"][-1]


# -- stiffness ---------------------------------------------------------------------


@pytest.mark.parametrize("version", VERSIONS)
def test_a_stiff_model_goes_to_cvode_and_follows_its_closed_form(version):
    lam = 1e4
    results = {}
    for solver in ("auto", "dp54", "cvode"):
        cols, stats, _, _ = run({"s": (me("MeStiff", version), {"lambda": lam})}, stop=1.0, step=0.1,
                                record={"s": ["y"]}, tolerance=1e-8, me_solver=solver)
        err = max(abs(y - (math.cos(t) + math.exp(-lam * t))) for t, y in zip(cols["time"], cols["s.y"]))
        results[solver] = (err, me_stats(stats, "s"))
    auto = results["auto"][1]
    assert auto["switches"] == 1 and auto["solver"] == "CVode BDF"
    assert results["dp54"][1]["switches"] == 0
    # The explicit pair is held to its stability limit, h < 3.3 / lambda: an order of magnitude more work.
    assert auto["rhs"] * 10 < results["dp54"][1]["rhs"]
    for solver, (err, _) in results.items():
        assert err < 1e-6, (solver, err)


# -- inputs, in a system with Co-Simulation FMUs ------------------------------------------


PENDULUM = {"phi_start": 0.2, "Q": 50.0}


def lag_reference(t_end, k=1.0, T=0.5, L=1.0, g=9.81, Q=50.0, phi0=0.2):
    """MeLag driven by the Co-Simulation Pendulum's angle (in vacuum, no
    torque): scipy at rtol 1e-12 on both."""
    w0 = math.sqrt(g / L)

    def f(t, y):
        phi, w, x = y
        return [w, -(g / L) * math.sin(phi) - w0 / Q * w, (k * phi - x) / T]

    sol = solve_ivp(f, (0.0, t_end), [phi0, 0.0, 0.0], rtol=1e-12, atol=1e-14, dense_output=True, method="DOP853")
    return lambda t: sol.sol(t)[2]


@pytest.mark.parametrize("version", VERSIONS)
def test_inputs_reach_the_integrator_as_the_couplings_polynomials(version):
    """A Co-Simulation FMU (the Pendulum) drives MeLag's input. With
    extrapolation of order 2 the wrapper evaluates the input polynomials at
    every right-hand side: the coupling error falls with the cube of the
    step (held inputs: with the step itself), and follows scipy's solution."""
    ref = lag_reference(3.0)
    errors = {}
    for order in (0, 2):
        for step in (0.05, 0.025):
            cols, _, _, _ = run({"p": (str(fmu_file("Pendulum")), PENDULUM), "lag": (me("MeLag", version), {})},
                                ["p.phi -> lag.u"], stop=3.0, step=step, record={"lag": ["y", "e"]},
                                extrapolation=order, tolerance=1e-10)
            errors[order, step] = max(abs(y - ref(t)) for t, y in zip(cols["time"], cols["lag.y"]))
    assert errors[0, 0.05] / errors[0, 0.025] < 2.5, errors
    assert errors[2, 0.05] / errors[2, 0.025] > 6, errors
    assert errors[2, 0.025] < 0.01 * errors[0, 0.025], errors


@pytest.mark.parametrize("prediction", (False, True))
@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("version", VERSIONS)
def test_the_clock_with_a_model_exchange_pendulum_ticks_as_the_co_simulation_one(engine, version, prediction):
    """The clock's pendulum as a Model Exchange FMU (MePendulum, the same
    equations) with the Co-Simulation grasshopper escapement: the master
    locates the escapement's switches with rollbacks of the wrapper (FMU
    state and the wrapper's own), or with event prediction on the
    wrapper's output derivatives, and the clock runs as with the
    Co-Simulation pendulum, tick for tick."""
    links = ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w",
             "escapement.tau -> pendulum.tau_escapement"]
    esc = (str(fmu_file("GrasshopperEscapement")), {"torque": 0.004, "phi_r": math.radians(2)})
    phi0 = math.radians(6)
    common = dict(links=links, stop=10.0, step=0.01, engine=engine, tolerance=1e-11,
                  record={"pendulum": ["phi", "tick_time"]}, event_prediction=prediction)
    cs_cols, _, _, _ = run({"pendulum": (str(fmu_file("Pendulum")), {"phi_start": phi0, "rtol": 1e-11,
                                                                     "atol": 1e-13}), "escapement": esc},
                           **common)
    me_cols, stats, _, used = run({"pendulum": (me("MePendulum", version), {"phi_start": phi0}),
                                   "escapement": esc}, **common)
    assert used == engine
    assert stats["events"] > 0
    assert (stats["predicted_landings"] if prediction else stats["rollbacks"]) > 0
    err = max(abs(a - b) for a, b in zip(cs_cols["pendulum.phi"], me_cols["pendulum.phi"]))
    assert err < 1e-7, err
    ticks_cs = sorted(set(cs_cols["pendulum.tick_time"]) - {0.0})
    ticks_me = sorted(set(me_cols["pendulum.tick_time"]) - {0.0})
    assert len(ticks_me) == len(ticks_cs) >= 4  # a period of 2 s
    assert max(abs(a - b) for a, b in zip(ticks_cs, ticks_me)) < 1e-8


# -- both engines ------------------------------------------------------------------------------


CASES = {
    "oscillator": ({"o": ("MeOscillator", {})}, [], {"o": ["x", "v"]}, {}),
    "ball": ({"b": ("MeBall", {})}, [], {"b": ["h", "v", "t_bounce"]}, {}),
    "timer": ({"t": ("MeTimer", {})}, [], {"t": ["x", "phase", "turns"]}, {}),
    "stiff": ({"s": ("MeStiff", {"lambda": 1e4})}, [], {"s": ["y"]}, {}),
    "lag": ({"p": ("Pendulum", PENDULUM), "lag": ("MeLag", {})}, ["p.phi -> lag.u"],
            {"lag": ["y", "e"]}, {"extrapolation": 2}),
    # a Model Exchange output (with its derivatives, cwme_getOutputDerivatives) into a Model Exchange input,
    # each stepped alone (as a group: tests/test_me_group.py)
    "me_to_me": ({"o": ("MeOscillator", {}), "lag": ("MeLag", {})}, ["o.x -> lag.u"], {"lag": ["y"]},
                 {"extrapolation": 2, "me_groups": False}),
    "clock": ({"pendulum": ("MePendulum", {}),
               "escapement": ("GrasshopperEscapement", {"torque": 0.004, "phi_r": 0.035})},
              ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w",
               "escapement.tau -> pendulum.tau_escapement"], {"pendulum": ["phi", "w", "tick_time"]}, {}),
}


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("case", list(CASES))
def test_both_engines_give_the_same_bits(case, version):
    components, links, record, extra = CASES[case]

    def path(name):
        return me(name, version) if name.startswith("Me") else str(fmu_file(name))

    comps = {n: (path(f), p) for n, (f, p) in components.items()}
    out = {engine: run(comps, links, stop=2.0, step=0.05, record=record, engine=engine, tolerance=1e-9, **extra)
           for engine in ENGINES}
    assert out["compiled"][3] == "compiled"
    (cols_py, stats_py, _, _), (cols_c, stats_c, _, _) = out["python"], out["compiled"]
    assert cols_py == cols_c
    assert stats_py == stats_c


@pytest.mark.parametrize("version", VERSIONS)
def test_a_saved_state_replays_the_same_bits(version):
    """fmi2GetFMUstate with the wrapper's own state: a step repeated from a restored state gives the same bits."""
    with System({"b": (me("MeBall", version), {})}, [], MasterSettings(step=0.05, engine="python"),
                record={"b": ["h", "v"]}) as s:
        m = s.master
        m.run_until(0.4)
        inst = s.instances["b"]
        inst.save_state(m.t)
        t = m.t
        first = []
        for _ in range(4):
            m.advance(m.t, 0.05)
            first.append(inst.get_real(["h", "v"]))
        inst.restore_state(t)
        m.t = t
        again = []
        for _ in range(4):
            m.advance(m.t, 0.05)
            again.append(inst.get_real(["h", "v"]))
        assert first == again


# -- scenes, settings, bad input --------------------------------------------------------------------


def write_scene(tmp_path, fmu, extra="", interface='interface = "model-exchange"'):
    scene = tmp_path / "me.toml"
    scene.write_text(f"""
[scene]
title = "a Model Exchange FMU"

[components.ball]
fmu = "{fmu}"
{interface}

[experiment]
stop = "1 s"

[master]
step = "0.05 s"
{extra}

[record]
outputs = ["ball.h"]

[analysis]
kind = "time_series"
""")
    return scene


def test_a_scene_runs_a_model_exchange_component_and_reports_its_statistics(tmp_path, capsys):
    import json

    scene = write_scene(tmp_path, me("MeBall"), 'me_solver = "dop853"')
    rc, _, err = run_cli(capsys, ["run", scene, "--out", tmp_path / "out", "--no-progress"])
    assert rc == 0, err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    s = summary["statistics"]["model_exchange"]["ball"]
    assert s["solver"] == "DOP853" and s["state_events"] == 1 and s["tolerance"] == 1e-8  # a bounce at 0.45 s


@pytest.mark.parametrize("bad, needle", [
    ('interface = "me"', '"co-simulation" or "model-exchange"'),
    ('interface = "co-simulation"', "no Co-Simulation interface"),
])
def test_a_bad_interface_is_one_line(tmp_path, capsys, bad, needle):
    scene = write_scene(tmp_path, me("MeBall"), interface=bad)
    rc, _, err = run_cli(capsys, ["validate", scene])
    assert rc == 2 and len(err.strip().splitlines()) == 1 and "components.ball.interface" in err
    assert needle in err


def test_a_bad_solver_is_one_line(tmp_path, capsys):
    scene = write_scene(tmp_path, me("MeBall"), 'me_solver = "euler"')
    rc, _, err = run_cli(capsys, ["validate", scene])
    assert rc == 2 and len(err.strip().splitlines()) == 1 and "master.me_solver" in err and '"cvode"' in err


def test_a_model_exchange_only_fmu_runs_without_asking():
    cols, stats, _, _ = run({"b": (me("MeBall"), {})}, stop=0.5, record={"b": ["h"]})
    assert "b" in stats["model_exchange"] and cols["b.h"][-1] < 1.0


@pytest.mark.parametrize("engine", ENGINES)
def test_a_failing_integration_names_the_fmu_and_the_step(engine):
    """Derivatives that are not finite (lambda = NaN) stop the pair: one
    line naming the instance, the integrator and where."""
    from clockwork.errors import SimulationError

    with pytest.raises(SimulationError) as e:
        run({"s": (me("MeStiff"), {"lambda": float("nan")})}, stop=0.5, engine=engine, me_solver="dp54")
    text = str(e.value)
    assert "s: MeStiff" in text and "DP5(4)" in text and "not finite" in text and "\n" not in text


@pytest.mark.parametrize("engine", ENGINES)
def test_shooting_finds_the_same_orbit_with_a_model_exchange_pendulum(engine):
    """Shooting resets every FMU and runs one-period maps (fmi2Reset and
    initialization again, event location with rollback): the grasshopper
    clock's periodic orbit with MePendulum is the one with the
    Co-Simulation Pendulum."""
    from clockwork.analyses.steady_state import find_steady_state
    from clockwork.engine.shooting import Shooter

    links = ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w",
             "escapement.tau -> pendulum.tau_escapement"]
    esc = (str(fmu_file("GrasshopperEscapement")), {"torque": 0.004, "phi_r": math.radians(2)})
    orbits = {}
    for kind, pendulum in (("cs", (str(fmu_file("Pendulum")), {"rtol": 1e-11, "atol": 1e-13})),
                           ("me", (me("MePendulum"), {}))):
        comps = {"pendulum": pendulum, "escapement": esc}
        with System(comps, links, MasterSettings(step=0.01, engine=engine, tolerance=1e-11),
                    record={"pendulum": ["tick_time", "tick_w", "amplitude"]}) as s:
            shooter = Shooter(s.master, {k: dict(v) for k, (_, v) in comps.items()}, "pendulum",
                              {"L": 1.0, "g": 9.81})
            orbits[kind] = find_steady_state(shooter, math.radians(5), math.radians(2), tolerance=1e-9)
    cs, me_ = orbits["cs"], orbits["me"]
    assert not me_.stalled and me_.iterations > 2
    assert abs(me_.period - cs.period) < 1e-10 and abs(me_.amplitude - cs.amplitude) < 1e-10


@pytest.mark.parametrize("implementation", ["", ' implementation="ModelExchange"', ' implementation="CoSimulation"'])
def test_an_ssp_runs_a_model_exchange_only_fmu(tmp_path, capsys, implementation):
    """An SSD whose pendulum is a Model Exchange only FMU (once refused) runs, mixed with a Co-Simulation
    escapement; asked for through an interface it lacks, it is one line naming the attribute."""
    import json
    import shutil

    res = tmp_path / "resources"
    res.mkdir()
    shutil.copy(me("MePendulum"), res / "MePendulum.fmu")
    shutil.copy(fmu_file("GrasshopperEscapement"), res / "GrasshopperEscapement.fmu")
    ssd = tmp_path / "SystemStructure.ssd"
    ssd.write_text("""<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription version="1.0" name="me"
    xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon"
    xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues">
  <ssd:System name="root">
    <ssd:Elements>
      <ssd:Component name="pendulum" source="resources/MePendulum.fmu"IMPL>
        <ssd:Connectors>
          <ssd:Connector name="phi" kind="output"><ssc:Real/></ssd:Connector>
          <ssd:Connector name="w" kind="output"><ssc:Real/></ssd:Connector>
          <ssd:Connector name="tau_escapement" kind="input"><ssc:Real/></ssd:Connector>
        </ssd:Connectors>
      </ssd:Component>
      <ssd:Component name="escapement" source="resources/GrasshopperEscapement.fmu">
        <ssd:Connectors>
          <ssd:Connector name="phi" kind="input"><ssc:Real unit="rad"/></ssd:Connector>
          <ssd:Connector name="w" kind="input"><ssc:Real unit="rad/s"/></ssd:Connector>
          <ssd:Connector name="tau" kind="output"><ssc:Real unit="N.m"/></ssd:Connector>
        </ssd:Connectors>
      </ssd:Component>
    </ssd:Elements>
    <ssd:Connections>
      <ssd:Connection startElement="pendulum" startConnector="phi" endElement="escapement" endConnector="phi"/>
      <ssd:Connection startElement="pendulum" startConnector="w" endElement="escapement" endConnector="w"/>
      <ssd:Connection startElement="escapement" startConnector="tau" endElement="pendulum" endConnector="tau_escapement"/>
    </ssd:Connections>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="3"/>
</ssd:SystemStructureDescription>
""".replace("IMPL", implementation))
    rc, _, err = run_cli(capsys, ["run", ssd, "--out", tmp_path / "out", "--no-progress"])
    if "CoSimulation" in implementation:
        assert rc == 2 and len(err.strip().splitlines()) == 1
        assert "implementation" in err and "no Co-Simulation interface" in err
        return
    assert rc == 0, err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["statistics"]["model_exchange"]["pendulum"]["state_events"] >= 2


def test_info_describes_a_model_exchange_fmu(capsys):
    rc, out, _ = run_cli(capsys, ["info", me("MeBall")])
    assert rc == 0
    assert "MeBall (FMI 2.0 Model Exchange)" in out and "needsCompletedIntegratorStep" in out
    assert re.search(r"continuous states \(Model Exchange\)\s+2", out)


def test_export_ssp_keeps_the_interface_a_scene_asks_for(tmp_path, capsys):
    """A component run as Model Exchange is exported with implementation="ModelExchange"."""
    import zipfile

    scene = write_scene(tmp_path, me("MeBall"))
    rc, _, err = run_cli(capsys, ["export-ssp", scene, "--out", tmp_path / "ball.ssp"])
    assert rc == 0, err
    ssd = zipfile.ZipFile(tmp_path / "ball.ssp").read("SystemStructure.ssd").decode()
    assert 'implementation="ModelExchange"' in ssd


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("engine", ENGINES)
def test_a_tunable_parameter_set_during_the_run_goes_through_event_mode(version, engine):
    """Model Exchange takes a tunable parameter in event mode only (the test
    FMUs refuse it otherwise): the wrapper enters event mode, sets it and
    settles, and the bounces follow the new restitution."""
    with System({"b": (me("MeBall", version), {})}, [], MasterSettings(step=0.05, engine=engine, tolerance=1e-10),
                record={"b": ["t_bounce"]}) as s:
        m = s.master
        m.run_until(0.3)  # before the first bounce
        s.instances["b"].set_values({"e": 0.5})
        m.discontinuity()
        seen = set()
        while m.t < 2.0 - 1e-12:
            m.run_until(min(2.0, m.t + 0.05))
            seen.add(s.output("b", "t_bounce"))
        stats = vars(m.stats)["model_exchange"]["b"]
    seen = sorted(seen - {0.0})
    expected = bounce_times(len(seen), e=0.5)
    assert len(seen) >= 3 and max(abs(a - b) for a, b in zip(seen, expected)) < 1e-8
    assert stats["input_events"] == 1


def test_a_model_exchange_element_whose_binary_lacks_the_functions_is_one_line(tmp_path, capsys):
    """The Pendulum declared Model Exchange only: its binary has no
    fmi2CompletedIntegratorStep (bad input, as another unloadable binary)."""
    import zipfile

    fmu = tmp_path / "PendulumME.fmu"
    with zipfile.ZipFile(fmu_file("Pendulum")) as src, zipfile.ZipFile(fmu, "w") as dst:
        for info in src.infolist():
            data = src.read(info)
            if info.filename == "modelDescription.xml":
                text = re.sub(r"<CoSimulation\b.*?</CoSimulation>|<CoSimulation\b[^>]*/>",
                              '<ModelExchange modelIdentifier="Pendulum"/>', data.decode(), count=1, flags=re.S)
                assert "<CoSimulation" not in text
                data = text.encode()
            dst.writestr(info, data)
    scene = write_scene(tmp_path, fmu, interface="")
    scene.write_text(scene.read_text().replace('"ball.h"', '"ball.phi"'))
    rc, _, err = run_cli(capsys, ["run", scene, "--out", tmp_path / "out", "--no-progress"])
    assert rc == 2 and len(err.strip().splitlines()) == 1
    assert "PendulumME.fmu" in err and "undefined symbol: fmi2" in err and "Traceback" not in err


@pytest.mark.parametrize("version", VERSIONS)
def test_outputs_that_are_states_have_their_derivatives(version):
    """dx/dt = v and d2x/dt2 = a of the oscillator (v is a state too), as the
    master's extrapolation and event location ask for them; an output that
    is no state has none."""
    with System({"o": (me("MeOscillator", version), {})}, [], MasterSettings(step=0.1, engine="python",
                                                                             tolerance=1e-10),
                record={"o": ["x", "v"]}) as s:
        s.master.run_until(1.0)
        inst = s.instances["o"]
        x, v = inst.get_real(["x", "v"])
        w, zeta = 2 * math.pi, 0.05
        assert inst.max_output_derivative_order == 2
        assert inst.output_derivatives(["x"], 1) == [v]
        assert inst.output_derivatives(["x"], 2) == pytest.approx([-w * w * x - 2 * zeta * w * v], rel=1e-12)
        assert inst.output_derivatives(["v"], 1) == pytest.approx([-w * w * x - 2 * zeta * w * v], rel=1e-12)
        assert inst.output_derivatives(["v"], 2) is None  # a is no state


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("alone", [True, False], ids=["alone", "scene"])
def test_every_command_takes_a_model_exchange_only_fmu_alone_or_in_a_scene(tmp_path, capsys, version, alone):
    """`validate` instantiated every FMU through the Co-Simulation factory and
    crashed (a traceback) on an FMU without a Co-Simulation interface, where
    `run` used the factory that knows both: each command now takes one.
    ("scene" in its name: the sanitizer build's run leaves it out, as every
    test that draws: matplotlib aborts under the preloaded ASan runtime.)"""
    import json

    target = me("MeBall", version) if alone else write_scene(tmp_path, me("MeBall", version))
    rc, out, err = run_cli(capsys, ["validate", target])
    assert rc == 0 and err == "" and out.startswith("ok:"), err
    rc, out, err = run_cli(capsys, ["info", me("MeBall", version)])  # info takes an FMU or an SSP
    assert rc == 0 and err == "", err
    rc, _, err = run_cli(capsys, ["export-scene" if alone else "export-ssp", target,
                                  "--out", tmp_path / ("scene.toml" if alone else "ball.ssp")])
    assert rc == 0, err
    for engine in ENGINES:
        out_dir = tmp_path / f"out_{engine}"
        rc, _, err = run_cli(capsys, ["run", target, "--out", out_dir, "--no-progress", "--no-plot",
                                      "--set", f"master.engine={engine}"])
        assert rc == 0, err
        assert "model_exchange" in json.loads((out_dir / "summary.json").read_text())["statistics"]
    rc, _, err = run_cli(capsys, ["plot", out_dir])
    assert rc == 0, err
