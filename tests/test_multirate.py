"""Components at their own steps (multi-rate, engine/multirate.py): the
scene key `[components.X] step`, OSP stepSize and SSP osp:StepSizeHint,
what the master does across rates (libcosim's rule) and what it refuses in
one line, on both engines with the same bits (the compiled core's
cw_rates.c). The numbers against libcosim itself: tests/test_osp.py."""

import shutil
import textwrap

import numpy as np
import pytest

from cwtest import ROOT, assert_one_line_error, fmu_file, run_cli

from clockwork.engine import MasterSettings, System
from clockwork.errors import SceneError, SimulationError, UsageError
from clockwork.run.catalog import load_scene

# A pendulum driving Ziemkiewicz's mechanism vibration, which drives it back
# (no direct feedthrough either way); `{vibration}` adds keys to its table.
SCENE = textwrap.dedent("""\
    connections = ["pendulum.phi -> vibration.a1", "vibration.tau -> pendulum.tau_coupling"]

    [scene]
    title = "two rates"

    [components.pendulum]
    fmu = "Pendulum"
    parameters = {{ phi_start = 0.2 }}

    [components.vibration]
    fmu = "MechanismVibration"
    parameters = {{ kappa = 0, C1 = 20 }}
    {vibration}

    [experiment]
    stop = {stop}

    [master]
    step = 0.01
    {master}

    [record]
    outputs = ["pendulum.phi", "vibration.a2"]
    """)


def scene_file(tmp_path, vibration="step = 0.03", master="", stop="0.6", name="s.toml"):
    f = tmp_path / name
    f.write_text(SCENE.format(vibration=vibration, master=master, stop=stop))
    return f


def run(capsys, f, out, *more):
    rc, _, err = run_cli(capsys, ["run", f, "--out", out, "--no-progress", *more])
    assert rc == 0, err
    lines = (out / "timeseries.csv").read_text().splitlines()
    return lines, err


def columns(lines):
    data = np.array([[float(x) for x in line.split(",")] for line in lines[1:]])
    return data[:, 0], data[:, 1], data[:, 2]


ENGINES = ["python", "compiled"]


@pytest.mark.parametrize("order", ["jacobi", "gauss-seidel"])
def test_a_slow_component_steps_every_k_base_steps_with_its_inputs_held(tmp_path, capsys, order):
    """The vibration (every 3 base steps) changes its outputs at its own
    points only (what it gave there is held between them); the compiled
    core runs it (it fell back to Python before) with the Python engine's
    bits."""
    f = scene_file(tmp_path, master=f'order = "{order}"')
    lines, _ = run(capsys, f, tmp_path / "out")
    t, phi, a2 = columns(lines)
    assert len(t) == 61
    for n in range(1, 61):  # between its points, what it gave at the last one
        if n % 3:
            assert a2[n] == a2[n - n % 3]
    assert a2[3] != 0.0 and a2[6] != a2[3]
    summary = (tmp_path / "out" / "summary.json").read_text()
    assert '"engine": "compiled"' in summary
    python, _ = run(capsys, f, tmp_path / "python", "--set", 'master.engine="python"')
    assert '"engine": "python"' in (tmp_path / "python" / "summary.json").read_text()
    assert python == lines



def test_a_step_is_a_whole_multiple_within_rounding():
    from clockwork.engine.multirate import decimation

    assert decimation(0.03, 0.01) == 3 and decimation(0.05, 0.01) == 5 and decimation(0.01, 0.01) == 1
    assert decimation(0.025, 0.01) is None and decimation(0.005, 0.01) is None and decimation(0.0, 0.01) is None
    assert decimation(float("nan"), 0.01) is None and decimation(-0.03, 0.01) is None
    assert decimation(3 * 0.1, 0.1) == 3  # 0.30000000000000004: within rounding


def test_every_component_at_the_base_step_is_the_single_rate_path_and_its_bits(tmp_path, capsys):
    a, _ = run(capsys, scene_file(tmp_path, vibration="", name="a.toml"), tmp_path / "a")
    b, _ = run(capsys, scene_file(tmp_path, vibration='step = "10 ms"', name="b.toml"), tmp_path / "b")
    assert a == b
    summary = (tmp_path / "b" / "summary.json").read_text()
    assert '"engine": "compiled"' in summary


def test_slow_component_differs_from_single_rate(tmp_path, capsys):
    a, _ = run(capsys, scene_file(tmp_path, vibration="", name="a.toml"), tmp_path / "a")
    b, _ = run(capsys, scene_file(tmp_path, name="b.toml"), tmp_path / "b")
    ta, phia, _ = columns(a)
    tb, phib, _ = columns(b)
    assert np.array_equal(ta, tb)
    assert np.max(np.abs(phia - phib)) > 1e-6


BAD = {
    "not a multiple": ("step = 0.025", "", ["components.vibration.step", "whole multiple of master.step (0.01 s)",
                                           "0.025 s"]),
    "below the base step": ("step = 0.005", "", ["components.vibration.step", "whole multiple"]),
    "zero": ("step = 0", "", ["components.vibration.step", "> 0"]),
    "negative": ("step = -0.03", "", ["components.vibration.step"]),
    "text": ('step = "fast"', "", ["components.vibration.step"]),
    "a bool": ("step = true", "", ["components.vibration.step"]),
    "not finite": ("step = inf", "", ["components.vibration.step"]),
    "longer than the run": ("step = 1.2", "", ["components.vibration.step", "at most the run's span (0.6 s)",
                                               "would never step"]),
    "strong coupling": ("step = 0.03", "iterations = 3", ["components.vibration.step",
                                                         "master.iterations = 3", "different rates",
                                                         "vibration every 3"]),
    "step doubling": ("step = 0.03", "richardson = true", ["components.vibration.step", "master.richardson",
                                                                "different rates"]),
}


@pytest.mark.parametrize("case", list(BAD))
def test_what_multirate_does_not_do_is_one_line(tmp_path, capsys, case):
    vibration, master, needles = BAD[case]
    f = scene_file(tmp_path, vibration=vibration, master=master)
    for command in ("validate", "run"):
        rc, _, err = run_cli(capsys, [command, f, *(["--out", tmp_path / "o", "--no-progress"]
                                                    if command == "run" else [])])
        assert_one_line_error(rc, err, str(f), *needles)
    assert not (tmp_path / "o").exists()


def test_a_stop_off_the_base_grid_is_refused(tmp_path, capsys):
    f = scene_file(tmp_path, stop="0.605")
    rc, _, err = run_cli(capsys, ["validate", f])
    assert_one_line_error(rc, err, "experiment.stop", "whole number of base steps")


def test_event_location_across_rates_is_refused_where_indicators_read_a_slow_component(tmp_path, capsys):
    """(Event location where the indicators are the base rate's:
    tests/test_multirate_timed.py.)"""
    f = tmp_path / "clock.toml"
    f.write_text(textwrap.dedent("""\
        connections = ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w",
                       "escapement.tau -> pendulum.tau_escapement"]
        [scene]
        title = "a slow pendulum"
        [components.pendulum]
        fmu = "Pendulum"
        step = 0.02
        [components.escapement]
        fmu = "GrasshopperEscapement"
        [experiment]
        stop = 1
        [master]
        step = 0.01
        """))
    rc, _, err = run_cli(capsys, ["validate", f])
    assert_one_line_error(rc, err, "components.pendulum.step", "master.event_location = true",
                          "escapement's event indicators read pendulum's outputs", "pendulum every 2")
    # without event location it runs: the escapement at the base rate reads the slow pendulum's held angle
    rc, _, err = run_cli(capsys, ["run", f, "--set", "master.event_location=false", "--out", tmp_path / "o",
                                  "--no-progress"])
    assert rc == 0, err


def test_validate_and_export_say_and_keep_the_steps(tmp_path, capsys):
    f = scene_file(tmp_path)
    rc, out, err = run_cli(capsys, ["validate", f])
    assert rc == 0, err
    assert "steps: pendulum 0.01 s (1 base step of 0.01 s), vibration 0.03 s (3 base steps of 0.01 s)" in out
    s = load_scene(f)
    assert s.components["vibration"].step == 0.03 and s.components["pendulum"].step is None
    # export-ssp writes osp:StepSizeHint, which reads back as the same step
    rc, out, err = run_cli(capsys, ["export-ssp", f, "--out", tmp_path / "x.ssp"])
    assert rc == 0, err
    back = load_scene(tmp_path / "x.ssp")
    assert back.components["vibration"].step == 0.03 and back.master.step == 0.01


@pytest.mark.parametrize("engine", ["auto", *ENGINES])
def test_the_system_api_takes_rates_on_both_engines(engine):
    comps = {"p": ("Pendulum", {"phi_start": 0.2}), "v": ("MechanismVibration", {"kappa": 0})}
    links = ["p.phi -> v.a1", "v.tau -> p.tau_coupling"]
    with System(comps, links, MasterSettings(step=0.01, engine=engine), rates={"v": 3}) as s:
        assert s.master.engine == ("python" if engine == "python" else "compiled")
        assert s.master.engine_reason is None
        assert s.master.rates == {"p": 1, "v": 3}
        s.master.run_until(0.09)
        assert s.master.t == pytest.approx(0.09) and s.master.stats.steps == 9
        with pytest.raises(UsageError, match=r"a step of 0.005 s from t = 0.09.* whole base steps \(0.01 s\) only"):
            s.master.step(0.005)
    with pytest.raises(SceneError, match="whole number of base steps"):
        System(comps, links, MasterSettings(step=0.01), rates={"v": 0})
    with pytest.raises(SceneError, match="no instance"):
        System(comps, links, MasterSettings(step=0.01), rates={"w": 2})


# Steps whose multiples are exact in binary: the grids of both runs are the same doubles.
EXACT = textwrap.dedent("""\
    [scene]
    title = "exact steps"
    [components.slow]
    fmu = "Pendulum"
    parameters = {{ phi_start = 0.1 }}
    {slow}
    [components.other]
    fmu = "Pendulum"
    [experiment]
    stop = 4
    [master]
    step = {base}
    [record]
    outputs = ["slow.phi"]
    """)


@pytest.mark.parametrize("engine", ENGINES)
def test_a_slow_component_takes_its_sampled_inputs_at_its_own_step_start(tmp_path, capsys, engine):
    """A pendulum every 2 base steps of 0.125 s, driven by an input file,
    gives at its own points the bits of the same pendulum run at 0.25 s:
    its inputs are the samples at its step's start, held over its step
    (the file drives a base-rate component too, at every base step)."""
    csv = tmp_path / "in.csv"
    csv.write_text("time,slow.tau_external,other.tau_external\n0,0,0\n1.3,0.01,0.02\n2.6,-0.005,0\n4,0,0\n")
    (tmp_path / "a.toml").write_text(EXACT.format(slow="step = 0.25", base=0.125))
    (tmp_path / "b.toml").write_text(EXACT.format(slow="", base=0.25))
    on = ("--set", f'master.engine="{engine}"')
    a, _ = run(capsys, tmp_path / "a.toml", tmp_path / "a", "--input", csv, *on)
    b, _ = run(capsys, tmp_path / "b.toml", tmp_path / "b", "--input", csv, *on)
    assert f'"engine": "{engine}"' in (tmp_path / "a" / "summary.json").read_text()
    ta, phia = (np.array([float(x) for x in col]) for col in zip(*(line.split(",") for line in a[1:])))
    tb, phib = (np.array([float(x) for x in col]) for col in zip(*(line.split(",") for line in b[1:])))
    assert len(ta) == 33 and len(tb) == 17
    assert np.array_equal(ta[::2], tb)
    assert np.array_equal(phia[::2], phib)  # bit for bit at its own points
    assert np.array_equal(phia[1::2], phia[:-1:2])  # held in between
    assert np.ptp(phib) > 0.1
    if engine == "compiled":  # the Python engine's bits, the slow component's and the fast one's
        both = ("--input", csv, "--set", 'record.outputs=["slow.phi", "other.phi"]')
        c, _ = run(capsys, tmp_path / "a.toml", tmp_path / "c", *both)
        p, _ = run(capsys, tmp_path / "a.toml", tmp_path / "p", *both, "--set", 'master.engine="python"')
        assert c == p and len({line.split(",")[2] for line in c[1:]}) > 20


@pytest.mark.parametrize("engine", ENGINES)
def test_a_sample_event_inside_a_base_step_is_refused_across_rates(tmp_path, capsys, engine):
    """The master across rates takes whole base steps only: an input
    file's event (a jump at 1.3 s, off the grid of 0.125 s) fails the run
    in one line on either engine, rather than stepping over it."""
    csv = tmp_path / "in.csv"
    csv.write_text("time,other.tau_external\n0,0\n1.3,0\n1.3,0.01\n4,0.01\n")
    (tmp_path / "a.toml").write_text(EXACT.format(slow="step = 0.25", base=0.125))
    rc, _, err = run_cli(capsys, ["run", tmp_path / "a.toml", "--out", tmp_path / "a", "--no-progress",
                                  "--input", csv, "--set", f'master.engine="{engine}"'])
    assert rc == 1
    assert "the input samples' event at t = 1.3 s falls inside the base step from t = 1.25 s" in err


def test_an_algebraic_loop_across_rates_is_one_line(tmp_path, capsys):
    from cwtest import test_fmu

    s = test_fmu("TestSum")
    f = tmp_path / "loop.toml"
    f.write_text(textwrap.dedent(f"""\
        connections = ["add.y -> gain.u1", "gain.y -> add.u2"]
        [scene]
        title = "a loop across rates"
        [components.add]
        fmu = "{s}"
        parameters = {{ c = 1.0 }}
        [components.gain]
        fmu = "{s}"
        parameters = {{ k1 = 0.5, k2 = 0.0 }}
        step = 0.25
        [experiment]
        stop = 1.0
        [master]
        step = 0.125
        """))
    rc, _, err = run_cli(capsys, ["validate", f])
    assert_one_line_error(rc, err, str(f), "algebraic loop", "gain steps every 2 base steps", "master.step")
    comps = {"add": (str(s), {"c": 1.0}), "gain": (str(s), {"k1": 0.5, "k2": 0.0})}
    with pytest.raises(SceneError, match="gain steps every 2 base steps"):
        System(comps, ["add.y -> gain.u1", "gain.y -> add.u2"], MasterSettings(step=0.125), rates={"gain": 2})


def test_restart_runs_the_same_numbers_again_on_both_engines():
    comps = {"p": ("Pendulum", {"phi_start": 0.2}), "v": ("MechanismVibration", {"kappa": 0, "C1": 20})}
    links = ["p.phi -> v.a1", "v.tau -> p.tau_coupling"]
    runs = []
    for engine in ENGINES:
        with System(comps, links, MasterSettings(step=0.01, engine=engine), rates={"v": 3},
                    record={"p": ["phi"], "v": ["a2"]}) as s:
            s.master.run_until(0.3)
            first = (s.output("p", "phi"), s.output("v", "a2"))
            s.restart({"p": {"phi_start": 0.2}, "v": {"kappa": 0, "C1": 20}})
            assert s.master.t == 0.0
            s.master.run_until(0.3)
            assert (s.output("p", "phi"), s.output("v", "a2")) == first
            runs.append(first)
    assert runs[0] == runs[1]


def test_a_sweep_of_the_base_step_is_checked_at_every_point(tmp_path, capsys):
    f = scene_file(tmp_path)
    f.write_text(f.read_text() + '\n[sweep]\naxes = [{ parameter = "master.step", values = [0.01, 0.02] }]\n')
    rc, _, err = run_cli(capsys, ["validate", f])
    assert_one_line_error(rc, err, "components.vibration.step", "whole multiple of master.step (0.02 s)")


def test_an_analysis_that_chooses_its_own_steps_is_one_line(tmp_path, capsys):
    f = scene_file(tmp_path)
    f.write_text(f.read_text() + '\n[analysis]\nkind = "steady_state"\n')
    rc, _, err = run_cli(capsys, ["validate", f])
    assert_one_line_error(rc, err, str(f), "analysis.kind", "time_series or ticks", "vibration (0.03 s)")


def test_an_osp_step_of_whole_nanosecond_base_steps_is_no_warning(tmp_path, capsys):
    """3e-4 s is 3 base steps of 1e-4 s in libcosim's whole nanoseconds,
    though 3 * 1e-4 is not 3e-4 in binary: no warning (there was one)."""
    shutil.copy(fmu_file("Pendulum"), tmp_path / "Pendulum.fmu")
    f = tmp_path / "OspSystemStructure.xml"
    f.write_text(textwrap.dedent("""\
        <OspSystemStructure xmlns="http://opensimulationplatform.com/MSMI/OSPSystemStructure" version="0.1">
          <StartTime>0</StartTime><EndTime>0.0012</EndTime><BaseStepSize>1e-4</BaseStepSize>
          <Simulators>
            <Simulator name="a" source="Pendulum.fmu"/>
            <Simulator name="b" source="Pendulum.fmu" stepSize="3e-4"/>
            <Simulator name="c" source="Pendulum.fmu" stepSize="2.5e-4"/>
          </Simulators>
        </OspSystemStructure>"""))
    rc, out, err = run_cli(capsys, ["validate", f])
    assert rc == 0, err
    assert "b 0.0003 s (3 base steps" in out and "c 0.0002 s (2 base steps" in out
    assert "'b'" not in err and "Simulator 'c' stepSize='2.5e-4': libcosim steps c every 2 base steps" in err


@pytest.mark.parametrize("engine", ENGINES)
def test_a_loop_among_base_rate_components_still_solves_beside_a_slow_one(engine):
    """An algebraic loop whose members step at the base step is solved at
    every base step as before: a slow component elsewhere changes none of
    its bits."""
    from cwtest import test_fmu

    s = str(test_fmu("TestSum"))
    loop = {"add": (s, {"c": 1.0}), "gain": (s, {"k1": 0.5, "k2": 0.0})}
    links = ["add.y -> gain.u1", "gain.y -> add.u2"]
    record = {"add": ["y"], "gain": ["y"]}

    def run(components, **rates):
        values = []
        with System(components, links, MasterSettings(step=0.125, engine=engine), record=record,
                    **({"rates": rates} if rates else {})) as sys_:
            for k in range(1, 9):
                sys_.master.run_until(k * 0.125)
                values.append((sys_.output("add", "y"), sys_.output("gain", "y")))
            return values, sys_.master.stats.loop_iterations

    alone = run(loop)
    beside = run({**loop, "slow": ("Pendulum", {})}, slow=4)
    assert alone == beside and alone[1] > 0


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("order", ["jacobi", "gauss-seidel"])
def test_base_rate_components_keep_their_bits_beside_an_unconnected_slow_one(order, engine):
    comps = {"p": ("Pendulum", {"phi_start": 0.2}), "v": ("MechanismVibration", {"kappa": 0, "C1": 20})}
    links = ["p.phi -> v.a1", "v.tau -> p.tau_coupling"]

    def run(components, **rates):
        with System(components, links, MasterSettings(step=0.01, order=order, engine=engine),
                    record={"p": ["phi"], "v": ["a2"]}, **({"rates": rates} if rates else {})) as s:
            s.master.run_until(0.5)
            return s.output("p", "phi"), s.output("v", "a2")

    assert run(comps) == run({**comps, "slow": ("Pendulum", {})}, slow=3)


def test_an_integer_passes_across_rates_at_the_shared_points():
    """An Integer link from a fast component (its step count) into a slow
    one (every 3 base steps) passes at the slow one's step starts and is
    held between: the slow one's y_int = p_int + u_int, read after its own
    steps, shows the count at its last step's start."""
    from cwtest import test_fmu

    s = str(test_fmu("TestTypes"))
    comps = {"a": (s, {}), "b": (s, {"p_int": 100})}
    seen = []
    with System(comps, ["a.count -> b.u_int"], MasterSettings(step=0.125), rates={"b": 3}) as sys_:
        for k in range(1, 10):
            sys_.master.run_until(k * 0.125)
            seen.append(tuple(sys_.instances[i].get_values([v])[0]
                              for i, v in (("a", "count"), ("b", "count"), ("b", "y_int"))))
    assert [a for a, _, _ in seen] == list(range(1, 10))
    assert [b for _, b, _ in seen] == [0, 0, 1, 1, 1, 2, 2, 2, 3]
    # b's step ending at base step 3 started at 0 (a.count = 0), the next at 3 (a.count = 3), then at 6
    assert [y for _, _, y in seen] == [100, 100, 100, 100, 100, 103, 103, 103, 106]


def test_large_coprime_factors_step_without_a_table_of_their_period():
    """Factors 997 and 991 (a period of 988,027 base steps) step as any
    others: the due components are found at each step, not tabled."""
    comps = {"p": ("Pendulum", {}), "a": ("Pendulum", {}), "b": ("Pendulum", {})}
    seen = []
    for engine in ENGINES:
        with System(comps, ["a.phi -> b.tau_external"], MasterSettings(step=1e-3, engine=engine),
                    rates={"a": 997, "b": 991}, record={"a": ["phi"], "b": ["phi"]}) as s:
            assert s.master.engine == engine and s.master._multirate.due is None
            s.master.run_until(2.0)
            assert s.master.t == pytest.approx(2.0)
            assert s.output("a", "phi") != s.instances["a"].get_real(["phi_start"])[0]
            seen.append((s.output("a", "phi"), s.output("b", "phi")))
    assert seen[0] == seen[1]


def test_what_the_core_does_not_do_across_rates_is_named_where_the_engine_is_chosen():
    """compiled.unsupported_rates decides: what multirate.py refuses today
    is refused before either engine steps, and were the Python engine to do
    it, "auto" would give it to Python rather than the core doing it
    otherwise."""
    from clockwork.engine.compiled import unsupported_rates

    rates = {"p": 1, "v": 3}
    assert unsupported_rates(MasterSettings(step=0.01), rates, {"p": [], "v": []}) is None
    assert unsupported_rates(MasterSettings(step=0.01, extrapolation=1), {"p": 1}, {}) is None
    for settings, needle in ((MasterSettings(step=0.01, extrapolation=2), "master.extrapolation = 2"),
                             (MasterSettings(step=0.01, iterations=3), "master.iterations = 3"),
                             (MasterSettings(step=0.01), "master.event_location = true")):
        why = unsupported_rates(settings, rates, {"p": ["z"], "v": []})
        assert why is not None and needle in why and "v every 3" in why
    assert unsupported_rates(MasterSettings(step=0.01, event_location=False), rates, {"p": ["z"]}) is None


def test_the_compiled_core_names_a_factor_it_cannot_count():
    comps = {"p": ("Pendulum", {}), "a": ("Pendulum", {})}
    with System(comps, [], MasterSettings(step=1e-3), rates={"a": 2 ** 31}) as s:
        assert s.master.engine == "python" and "a every 2147483648 base steps" in s.master.engine_reason
    with pytest.raises(SceneError, match="counts at most 2147483647 base steps"):
        System(comps, [], MasterSettings(step=1e-3, engine="compiled"), rates={"a": 2 ** 31})


def test_fmi3_clocks_and_rates_together_are_one_line(tmp_path, capsys):
    """A scene with FMI 3.0 clocks lands a communication point of every
    component on each tick: components at their own steps are refused
    there, in the scene and in System (the clocked master would not take
    the rates: before, it ran every component at the base step)."""
    from cwtest import test_fmu

    ticker, counter = (str(test_fmu(f"fmi3/{n}")) for n in ("Ticker", "Counter"))
    f = tmp_path / "s.toml"
    f.write_text('connections = ["tk.tick -> ct.tooth", "tk.n -> ct.step_by"]\n[scene]\ntitle = "t"\n'
                 f'[components.tk]\nfmu = "{ticker}"\n[components.ct]\nfmu = "{counter}"\nstep = 0.5\n'
                 '[experiment]\nstop = 1\n[master]\nstep = 0.25\n')
    rc, _, err = run_cli(capsys, ["validate", f])
    assert_one_line_error(rc, err, str(f), "components.ct.step", "FMI 3.0 clocks (tk, ct)")
    with pytest.raises(SceneError, match="a scene with FMI 3.0 clocks"):
        System({"tk": (ticker, {}), "ct": (counter, {})}, ["tk.tick -> ct.tooth", "tk.n -> ct.step_by"],
               MasterSettings(step=0.25), rates={"ct": 2})


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("order", ["jacobi", "gauss-seidel"])
def test_three_rates_with_a_feedthrough_between_give_the_same_bits_on_both_engines(order, threads):
    """Factors 1, 2 and 3 with a feedthrough-only component at the base
    rate between a slow source and a fast target (it reads the slow one's
    held angle, updated at t + h), a scaled link, links across every pair
    of rates: every output at every base step, bit for bit, on both engines."""
    from cwtest import test_fmu
    from clockwork.engine.wiring import Link

    s = str(test_fmu("TestSum"))
    comps = {"p1": ("Pendulum", {"phi_start": 0.2}), "s2": ("Pendulum", {"phi_start": 0.1}),
             "sum": (s, {"k1": 0.01, "k2": -0.02, "c": 0.0}), "v3": ("MechanismVibration", {"kappa": 0, "C1": 20})}
    links = ["s2.phi -> sum.u1", "p1.phi -> sum.u2", "sum.y -> p1.tau_external", "p1.phi -> v3.a1",
             Link("v3", "tau", "s2", "tau_coupling", 0.5, 1e-4), "s2.w -> p1.tau_coupling"]
    record = {"p1": ["phi", "w"], "s2": ["phi", "w"], "sum": ["y"], "v3": ["a2", "tau"]}
    runs = []
    for engine in ENGINES:
        rows = []
        with System(comps, links, MasterSettings(step=0.01, order=order, engine=engine, threads=threads),
                    rates={"s2": 2, "v3": 3}, record=record) as sys_:
            assert sys_.master.engine == engine
            assert (threads > 1) == any("master.threads = 2" in n for n in sys_.master.notes)
            for k in range(1, 61):
                sys_.master.run_until(k * 0.01)
                rows.append([sys_.output(i, v) for i, vs in record.items() for v in vs])
        runs.append(rows)
    assert runs[0] == runs[1]
    y = [r[4] for r in runs[0]]
    assert len(set(y)) > 30  # the feedthrough follows p1 at every base step


@pytest.mark.parametrize("engine", ENGINES)
def test_a_time_event_inside_a_base_step_is_refused_across_rates(engine):
    """An FMI 3.0 FMU announcing time events every 0.3 s beside a slow
    pendulum, base step 0.25 s: the master across rates does not shorten a
    step, so the event at 0.3 s fails the run in one line, on either engine
    (the same line), after the steps before it."""
    from cwtest import test_fmu

    comps = {"b": (str(test_fmu("fmi3/Early")), {"v0": 1.0, "period": 0.3}), "p": ("Pendulum", {})}
    with System(comps, [], MasterSettings(step=0.25, engine=engine, event_location=False), rates={"p": 2}) as s:
        assert s.master.engine == engine
        with pytest.raises(SimulationError, match=r"^a time event an FMU announced at t = 0\.3 s falls inside the "
                                                  r"base step from t = 0\.25 s: components step at different rates"):
            s.master.run_until(1.0)
        assert s.master.t == 0.25 and s.master.stats.steps == 1
