"""Algebraic loops (clockwork/engine/loops.py, wiring.py), on both engines.

Test FMUs (tests/models): TestSum, y = k1 u1 + k2 u2 + c with direct
feedthrough from both inputs (a gain with k2 = 0, an adder with k1 = k2 =
1), and TestIntegrator, dx/dt = k u with y = x whose output declares no
dependencies (FMI: "depends on every input"), so that two of them form a
formal loop. The gain-adder loop a = c + g, g = K a has the fixed point
a = c / (1 - K): plain iteration converges for |K| < 1, diverges for |K| > 1
(the Newton fallback solves it), and there is none for K = 1.
"""

from __future__ import annotations

import json
import math
from types import SimpleNamespace

import pytest

from clockwork.engine import MasterSettings, System
from clockwork.engine.recording import Recorder
from clockwork.engine.wiring import Link, build, loop_name
from clockwork.errors import SceneError, SimulationError
from cwtest import assert_one_line_error, run_cli, test_fmu

ENGINES = ["python", "compiled"]
H = 0.125  # s: a step whose multiples are exact, so that the grid and the peers' clocks agree
LOOP = ["add.y -> gain.u1", "gain.y -> add.u2"]


def _loop(K: float, c: float = 1.0):
    s = str(test_fmu("TestSum"))
    return {"add": (s, {"c": c}), "gain": (s, {"k1": K, "k2": 0.0})}


def _run(components, links, steps: int, record: dict, **settings):
    """Run `steps` steps; (the recorded columns at every point, statistics, engine)."""
    with System(components, links, MasterSettings(step=H, **settings), record=record) as s:
        outputs = [(i, v) for i, names in record.items() for v in names]
        rec = Recorder(s.master, outputs)
        rec.start()
        s.master.run_until(steps * H, rec)
        return rec.columns, vars(s.master.stats), s.master.engine


def _both(components, links, steps, record, **settings):
    """The run on both engines, checked to be the same bits; the Python one's result."""
    runs = [_run(components, links, steps, record, engine=e, **settings) for e in ENGINES]
    assert [r[2] for r in runs] == ENGINES
    assert runs[0][0] == runs[1][0]  # every recorded value, bit for bit
    assert runs[0][1] == runs[1][1]  # and the statistics
    return runs[0][0], runs[0][1]


# -- "solve" -----------------------------------------------------------------------


@pytest.mark.parametrize("K, fallback", [(0.5, False), (-0.5, False), (3.0, True), (-2.0, True), (0.999, True)])
def test_a_real_loop_is_solved_to_its_fixed_point(K, fallback):
    # |K| < 1: plain iteration contracts (K = 0.999 too slowly: 50 sweeps,
    # then Newton); |K| > 1 it diverges and the Newton fallback solves it.
    # A Gauss-Seidel sweep goes once round the loop: the residual shrinks by |K|.
    c = 1.0
    cols, stats = _both(_loop(K, c), LOOP, 8, {"add": ["y"], "gain": ["y"]})
    exact = c / (1.0 - K)
    tol = MasterSettings().iteration_tolerance
    assert len(cols["time"]) == 9
    for a, g in zip(cols["add.y"], cols["gain.y"]):
        # A residual r within tol * max(1, |x|) leaves x within r / (1 - K) of the fixed point.
        assert abs(a - exact) <= 2 * tol * max(1.0, abs(exact)) / abs(1.0 - K), (a, exact)
        assert abs(g - K * a) <= 2 * tol * max(1.0, abs(g)), (g, K * a)
    assert stats["loop_iterations"] > 0
    assert (stats["loop_fallbacks"] > 0) == fallback


def test_a_loop_of_an_fmi2_and_an_fmi3_instance_is_solved():
    # FMI 3.0 allows setting inputs and getting outputs in Step Mode and in
    # Initialization Mode as FMI 2.0 does: TestSum's FMI 3.0 build as the gain.
    K, c = 3.0, 1.0
    comps = {"add": (str(test_fmu("TestSum")), {"c": c}),
             "gain": (str(test_fmu("TestSum").parent / "fmi3" / "TestSum.fmu"), {"k1": K, "k2": 0.0})}
    cols, stats = _both(comps, LOOP, 4, {"add": ["y"], "gain": ["y"]})
    assert all(abs(a - c / (1.0 - K)) <= 1e-12 for a in cols["add.y"]), cols["add.y"]
    assert stats["loop_fallbacks"] > 0


def test_the_loop_test_fmus_are_valid():
    from fmpy.validation import validate_fmu

    for fmu in (test_fmu("TestSum"), test_fmu("TestIntegrator"), test_fmu("TestSum").parent / "fmi3" / "TestSum.fmu"):
        assert validate_fmu(str(fmu)) == [], fmu


def test_a_loop_through_a_linear_transformation_is_solved():
    # One adder feeding itself through a link of factor K and offset d:
    # a = c + K a + d.
    K, c, d = 2.5, 1.0, 0.5
    s = str(test_fmu("TestSum"))
    cols, stats = _both({"add": (s, {"c": c})}, [Link("add", "y", "add", "u2", K, d)], 4, {"add": ["y"]})
    exact = (c + d) / (1.0 - K)
    assert all(abs(a - exact) <= 1e-12 for a in cols["add.y"]), (cols["add.y"], exact)
    assert stats["loop_fallbacks"] > 0


def test_a_formal_loop_is_the_explicit_euler_oscillator():
    # Two integrators whose outputs declare no dependencies but depend on no
    # input: x1' = x2, x2' = -x1. Both are stepped with the inputs of the
    # step's start, so w = x1 + i x2 follows w(n+1) = (1 - i h) w(n): at point
    # n, |w| = (1 + h^2)^(n/2) and arg w = -n atan(h). The loop settles in at
    # most two sweeps wherever outputs are brought up to date: no fallback.
    integ = str(test_fmu("TestIntegrator"))
    comps = {"x1": (integ, {"k": 1.0, "x0": 1.0}), "x2": (integ, {"k": -1.0, "x0": 0.0})}
    n = 40
    cols, stats = _both(comps, ["x1.y -> x2.u", "x2.y -> x1.u"], n, {"x1": ["y"], "x2": ["y"]})
    for k, (a, b) in enumerate(zip(cols["x1.y"], cols["x2.y"])):
        r, phi = (1.0 + H * H) ** (k / 2), -k * math.atan(H)
        assert abs(a - r * math.cos(phi)) <= 1e-13 * r and abs(b - r * math.sin(phi)) <= 1e-13 * r, k
    assert stats["loop_fallbacks"] == 0
    # Three updates at the start (two in Initialization Mode, one after), one per step.
    assert 3 + n <= stats["loop_iterations"] <= 2 * (3 + n)


def test_a_loop_between_dynamic_steps_is_solved_where_gauss_seidel_passes_values_on():
    # d1 -> (add <-> gain) -> d2: in Gauss-Seidel order the loop is solved
    # after d1's step, so that d2 steps with the loop's newest output, and
    # again at the step's end; at every point add.y = (d1.x + c) / (1 - K).
    decay, s = str(test_fmu("TestDecay")), str(test_fmu("TestSum"))
    K, c = 0.5, 0.25
    comps = {"d1": (decay, {"k": 1.0, "x0": 1.0}), **_loop(K, c), "d2": (decay, {"k": 2.0, "x0": 0.0})}
    links = ["d1.x -> add.u1", *LOOP, "add.y -> d2.v"]
    d2 = {}
    for order in ("gauss-seidel", "jacobi"):
        cols, stats = _both(comps, links, 16, {"d1": ["x"], "add": ["y"], "d2": ["x"]}, order=order)
        for x, a in zip(cols["d1.x"], cols["add.y"]):
            assert abs(a - (x + c) / (1.0 - K)) <= 4e-10 * max(1.0, abs(a)), (order, x, a)
        d2[order] = cols["d2.x"]
    # Without the loop solved between the steps, d2 would see the step's start in both orders.
    assert d2["gauss-seidel"][1:] != d2["jacobi"][1:]


def test_a_loop_without_a_solution_fails_in_one_line(capsys, tmp_path):
    # K = 1: a = c + a has no solution for c != 0.
    f = _scene(tmp_path, K=1.0)
    for engine in ENGINES:
        rc, _, err = run_cli(capsys, ["run", f, "--out", tmp_path / engine, "--no-progress",
                                      "--set", f"master.engine={engine}"])
        assert_one_line_error(rc, err, "t = 0.0 s: algebraic loop add -> gain -> add did not converge",
                              "master.iteration_tolerance", code=1)
    with pytest.raises(SimulationError, match="singular Jacobian"):
        _run(_loop(1.0), LOOP, 1, {"add": ["y"]})


def test_integer_links_in_a_loop_are_iterated_and_a_changing_one_fails_in_one_line():
    # TestTypes: y_int = p_int + u_int. Going round the loop adds pa + pb:
    # with pa + pb = 0 every value is a fixed point, else none.
    types = str(test_fmu("TestTypes"))
    links = ["a.y_int -> b.u_int", "b.y_int -> a.u_int"]
    with System({"a": (types, {"p_int": 3}), "b": (types, {"p_int": -3})}, links, MasterSettings(step=H)) as s:
        s.master.run_until(4 * H)
        assert s.master.engine == "python"  # the core passes Real links only, and says so
        assert s.instances["a"].get_integer(["y_int"]) == [3] and s.instances["b"].get_integer(["y_int"]) == [0]
        assert s.master.stats.loop_iterations > 0
    with pytest.raises(SimulationError) as e:
        System({"a": (types, {"p_int": 1}), "b": (types, {"p_int": 1})}, links, MasterSettings(step=H))
    assert "algebraic loop a -> b -> a did not converge" in str(e.value)
    assert "Integer link" in str(e.value) and "still changes" in str(e.value) and "\n" not in str(e.value)


# -- "delay" -----------------------------------------------------------------------


def _delayed(K: float, c: float, points: int, order: str) -> tuple[list[float], list[float]]:
    """The gain-adder loop broken by a one-step delay, as the FMUs compute it
    (a = 1 u1 + 1 u2 + c with u1 = 0, g = K u1 + 0 u2 + 0). The start, as
    libcosim's: the outputs at the inputs' start values (0), then one Jacobi
    evaluation per instance (2), the last one only set; the first step
    holds what the outputs at the start give."""
    def adder(g):
        return 1.0 * 0.0 + 1.0 * g + c

    def gain(a):
        return K * a + 0.0 * 0.0 + 0.0

    a, g = adder(0.0), gain(0.0)
    for _ in range(2):
        a, g = adder(g), gain(a)
    adds, gains = [a], [g]
    for _ in range(points - 1):
        if order == "jacobi":
            a, g = adder(g), gain(a)
        else:  # Gauss-Seidel: the gain, stepped after the adder, takes its newest output
            a = adder(g)
            g = gain(a)
        adds.append(a)
        gains.append(g)
    return adds, gains


@pytest.mark.parametrize("order", ["jacobi", "gauss-seidel"])
def test_delay_gives_the_delayed_recursion_and_its_closed_form(order):
    K, c, n = 0.5, 1.0, 30
    cols, stats = _both(_loop(K, c), LOOP, n, {"add": ["y"], "gain": ["y"]}, algebraic_loops="delay", order=order)
    adds, gains = _delayed(K, c, n + 1, order)
    assert cols["add.y"] == adds and cols["gain.y"] == gains  # bit for bit
    assert stats["loop_iterations"] == 0 and stats["loop_fallbacks"] == 0
    # The closed forms: Jacobi, a(i + 2) = c + K a(i) from the evaluations
    # a(0) = a(1) = c, where point k is evaluation k + 2 (so a = c/(1-K)
    # (1 - K^(m+1)) at evaluation 2m or 2m + 1); Gauss-Seidel, a(k + 1) =
    # c + K a(k) from point 1 on (the start is the peers' Jacobi one).
    fixed = c / (1.0 - K)
    for k, a in enumerate(cols["add.y"]):
        if order == "jacobi":
            closed = fixed * (1.0 - K ** ((k + 2) // 2 + 1))
        else:
            closed = fixed + (adds[1] - fixed) * K ** (k - 1) if k else adds[0]
        assert abs(a - closed) <= 1e-15 * fixed, (k, a, closed)


def test_delay_breaks_a_loop_that_solve_finds_without_a_solution():
    cols, _ = _both(_loop(1.0, 1.0), LOOP, 6, {"add": ["y"]}, algebraic_loops="delay", order="jacobi")
    assert cols["add.y"] == [2.0, 2.0, 3.0, 3.0, 4.0, 4.0, 5.0]  # a grows by c every second evaluation


@pytest.mark.parametrize("settings", [dict(), dict(algebraic_loops="delay"),
                                      dict(algebraic_loops="delay", order="jacobi")])
def test_a_restarted_system_gives_the_bits_of_a_new_one(settings):
    # A loop fed by a dynamic instance (d.x feeds add.u1, no feedthrough)
    # reads d's output before d is read in Initialization Mode: what the
    # last run left there must not reach the new start.
    decay = str(test_fmu("TestDecay"))
    comps = {**_loop(3.0), "d": (decay, {"x0": 1.0})}
    links = [*LOOP, "d.x -> add.u1", "add.y -> d.v"]
    for engine in ENGINES:
        runs = []
        with System(comps, links, MasterSettings(step=H, engine=engine, **settings), record={"add": ["y"]}) as s:
            for k in range(2):
                if k:
                    s.restart(s.parameters)
                rec = Recorder(s.master, [("add", "y")])
                rec.start()
                s.master.run_until(8 * H, rec)
                runs.append((rec.columns, vars(s.master.stats)))
        assert runs[0] == runs[1], engine


# -- settings, validate, statistics --------------------------------------------------


SCENE = """
connections = ["add.y -> gain.u1", "gain.y -> add.u2"]
[scene]
title = "gain and adder in feedback"
[components.add]
fmu = "{sum}"
parameters = {{ c = 1.0 }}
[components.gain]
fmu = "{sum}"
parameters = {{ k1 = {K}, k2 = 0.0 }}
[experiment]
stop = 1.0
[master]
step = 0.125
{master}
[record]
outputs = ["add.y", "gain.y"]
"""


def _scene(tmp_path, K: float = 0.5, master: str = "") -> object:
    f = tmp_path / "loop.toml"
    f.write_text(SCENE.format(sum=test_fmu("TestSum"), K=K, master=master))
    return f


@pytest.mark.parametrize("mode, how", [("solve", "solved to a fixed point at every communication point"),
                                       ("delay", "broken by a one-step delay")])
def test_validate_names_each_loop_and_the_mode(capsys, tmp_path, mode, how):
    f = _scene(tmp_path, master=f'algebraic_loops = "{mode}"')
    rc, out, err = run_cli(capsys, ["validate", f])
    assert rc == 0, err
    assert (f"note: algebraic loop add -> gain -> add (through add.y -> gain.u1, gain.y -> add.u2): {how} "
            f'(master.algebraic_loops = "{mode}")') in out.splitlines()


def test_the_summary_counts_loop_iterations_and_fallbacks(capsys, tmp_path):
    for K, fallbacks in ((0.5, False), (3.0, True)):
        out = tmp_path / f"out{K}"
        rc, _, err = run_cli(capsys, ["run", _scene(tmp_path, K=K), "--out", out, "--no-progress"])
        assert rc == 0, err
        stats = json.loads((out / "summary.json").read_text())["statistics"]
        assert stats["loop_iterations"] > 0 and (stats["loop_fallbacks"] > 0) == fallbacks


@pytest.mark.parametrize("value", ['"solved"', "1", "true", '""'])
def test_a_bad_algebraic_loops_setting_is_refused_in_one_line(capsys, tmp_path, value):
    f = _scene(tmp_path, master=f"algebraic_loops = {value}")
    rc, _, err = run_cli(capsys, ["validate", f])
    assert_one_line_error(rc, err, str(f), "master.algebraic_loops", '"solve"', '"delay"')
    rc, _, err = run_cli(capsys, ["validate", _scene(tmp_path), "--set", f"master.algebraic_loops={value}"])
    assert_one_line_error(rc, err, "master.algebraic_loops")
    with pytest.raises(SceneError, match="master.algebraic_loops"):
        MasterSettings(algebraic_loops=value.strip('"'))


# -- the wiring ------------------------------------------------------------------------


def _fake(n_inputs: int = 1):
    """An instance as the wiring sees it: output y depends on input u."""
    out = SimpleNamespace(causality="output", dependencies=[1])
    return SimpleNamespace(variables={"y": out, "u": SimpleNamespace(causality="input", dependencies=None)})


def test_loops_are_found_without_recursion_in_thousands_of_instances():
    # A ring of 5000 instances (deeper than Python's recursion limit), a
    # chain into it and two separate loops: each strongly connected component
    # is one loop, in instance order, after what feeds it.
    n = 5000
    names = [f"r{i}" for i in range(n)] + ["s", "a", "b", "c"]
    instances = {name: _fake() for name in names}
    links = [Link(f"r{i}", "y", f"r{(i + 1) % n}", "u") for i in range(n)]
    links += [Link("s", "y", "r0", "u"), Link("a", "y", "b", "u"), Link("b", "y", "a", "u"), Link("c", "y", "c", "u")]
    w = build(instances, links)
    assert sorted(map(tuple, w.loops)) == sorted([tuple(f"r{i}" for i in range(n)), ("a", "b"), ("c",)])
    assert w.evaluation_order.index("s") < w.evaluation_order.index("r0")
    ring = next(k for k, m in enumerate(w.loops) if len(m) == n)
    assert len(w.loop_links[ring]) == n
    assert loop_name(w.loops[ring], w.loop_links[ring]) == " -> ".join([f"r{i}" for i in range(n)] + ["r0"])
    # Broken by a delay, the members are stepped as dynamic instances.
    assert set(build(instances, links, algebraic_loops="delay").dynamic) >= {"a", "b", "c", "r0"}


def test_a_chain_keeps_its_order_and_has_no_loop():
    instances = {name: _fake() for name in "abcd"}
    links = [Link("c", "y", "b", "u"), Link("b", "y", "a", "u"), Link("d", "y", "c", "u")]
    w = build(instances, links)
    assert w.loops == [] and w.evaluation_order == ["d", "c", "b", "a"]
