"""The call sequence (FMI 2.0 4.2.4, FMI 3.0 Step Mode): an FMU that does
not declare, in clockwork's annotation, that its outputs may be read after
its inputs are set never sees a get after a set without a step between.

The test FMU (tests/strict_fmu.py, tests/data/strict/strict.c) returns an
error on such a get: y = gain * u + offset + slope * time, with direct
feedthrough. Each run below goes to its end, on both engines, with the
numbers a conforming master gives: fmpy's for the FMU alone with an input,
the source's new value in Gauss-Seidel order (the feedthrough FMU steps
after its source), the value at the step's start in Jacobi order, an
algebraic loop solved in Initialization Mode and delayed in the steps.
"""

from __future__ import annotations

import csv as csv_module
import math

import fmpy
import numpy as np
import pytest

import clockwork
from clockwork.engine import MasterSettings, System
from clockwork.engine.recording import Recorder
from clockwork.errors import SimulationError
from cwtest import fmu_file, run_cli, test_fmu

ENGINES = ["python", "compiled"]
VERSIONS = [2, 3]


@pytest.fixture(scope="module")
def strict():
    """{2: the FMI 2.0 build, 3: the FMI 3.0 build, "declares": an FMI 2.0
    build whose description claims outputs after inputs (falsely)}: strict_fmu.py."""
    return {2: test_fmu("Strict2"), 3: test_fmu("fmi3/Strict3"), "declares": test_fmu("Claims")}


def _run(components, links, stop, h, record, **settings):
    with System(components, links, MasterSettings(step=h, **settings), record=record) as s:
        rec = Recorder(s.master, [(i, v) for i, names in record.items() for v in names])
        rec.start()
        s.master.run_until(stop, rec)
        return rec.columns, s.master


@pytest.mark.parametrize("version", VERSIONS)
def test_the_strict_fmu_refuses_a_get_after_a_set_in_step_mode(strict, version):
    # The FMU itself, through fmpy: a get after a set in Initialization Mode
    # is fine, in Step Mode it is an error until the next step.
    md = fmpy.read_model_description(str(strict[version]))
    unzip = fmpy.extract(str(strict[version]))
    cls = fmpy.fmi3.FMU3Slave if version == 3 else fmpy.fmi2.FMU2Slave
    fmu = cls(guid=md.guid, unzipDirectory=unzip, modelIdentifier="Strict", instanceName="s")
    fmu.instantiate()
    try:
        if version == 3:
            fmu.enterInitializationMode()
            get, set_ = fmu.getFloat64, fmu.setFloat64
        else:
            fmu.setupExperiment(startTime=0.0)
            fmu.enterInitializationMode()
            get, set_ = fmu.getReal, fmu.setReal
        set_([1], [2.0])
        assert get([2]) == [2.0]
        fmu.exitInitializationMode()
        assert get([2]) == [2.0]
        set_([1], [3.0])
        with pytest.raises(Exception):
            get([2])
        fmu.doStep(0.0, 0.1)
        assert get([2]) == [3.0]
    finally:
        fmu.terminate()
        fmu.freeInstance()


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("version", VERSIONS)
def test_alone_with_an_input_it_gives_fmpys_numbers(strict, version, engine):
    # fmpy sets the inputs at t, steps, reads: y(t + h) = u(t).
    t = np.linspace(0.0, 1.0, 11)
    signal = np.array(list(zip(t, np.sin(3.0 * t))), dtype=[("time", "f8"), ("u", "f8")])
    ours = clockwork.simulate(str(strict[version]), stop_time=1.0, step_size=0.01, input=signal, output=["y"],
                              master={"engine": engine})
    theirs = fmpy.simulate_fmu(str(strict[version]), stop_time=1.0, step_size=0.01, input=signal, output=["y"])
    assert len(ours) == len(theirs) == 101
    assert list(ours["time"]) == list(theirs["time"])
    assert list(ours["y"]) == list(theirs["y"])


@pytest.mark.parametrize("engine", ENGINES)
def test_alone_with_an_input_file_from_the_command_line(strict, tmp_path, engine, capsys):
    csv = tmp_path / "u.csv"
    csv.write_text("time,u\n0,0\n0.5,1\n1,0\n")
    code, _, err = run_cli(capsys, ["run", strict[2], "--input", csv, "--out", tmp_path / "out",
                                    "--set", f'master.engine="{engine}"'])
    assert code == 0, err
    with open(tmp_path / "out" / "timeseries.csv") as f:
        rows = list(csv_module.DictReader(f))
    assert len(rows) == 101 and float(rows[-1]["time"]) == 1.0
    (y,) = [c for c in rows[0] if c.split(".")[-1] == "y"]
    # fmpy's sequence: y(t + h) = u(t), u the linear interpolation of the file.
    u = lambda t: 2.0 * t if t <= 0.5 else 2.0 - 2.0 * t  # noqa: E731
    times = [float(r["time"]) for r in rows]
    assert float(rows[0][y]) == 0.0
    for k in range(1, len(rows)):
        assert abs(float(rows[k][y]) - u(times[k - 1])) <= 1e-12, (times[k], rows[k][y])


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("order", ["gauss-seidel", "jacobi"])
def test_after_a_dynamic_source_it_steps_after_it(strict, version, engine, order):
    # The strict FMU is listed before its source: in Gauss-Seidel order it
    # still steps after it and gives the source's new value; in Jacobi
    # order the value at the step's start.
    comps = {"ft": (str(strict[version]), {}), "osc": (str(test_fmu("TestOscillator")), {"omega": 2.0})}
    cols, _ = _run(comps, ["osc.x -> ft.u"], 2.0, 0.05, {"osc": ["x"], "ft": ["y"]}, engine=engine, order=order)
    x, y = cols["osc.x"], cols["ft.y"]
    assert len(x) == 41
    assert y[0] == x[0]
    if order == "jacobi":
        assert y[1:] == x[:-1]
    else:
        assert y == x


def test_a_false_claim_is_followed(strict):
    # The annotation is what the master goes by: an FMU that claims outputs
    # after inputs gets today's sequence, which this one refuses.
    comps = {"ft": (str(strict["declares"]), {}), "osc": (str(test_fmu("TestOscillator")), {})}
    with pytest.raises(SimulationError, match="fmi2GetReal"):
        _run(comps, ["osc.x -> ft.u"], 1.0, 0.05, {"ft": ["y"]})


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("version", VERSIONS)
def test_an_algebraic_loop_is_solved_in_initialization_mode_and_delayed_in_the_steps(strict, version, engine,
                                                                                       capsys):
    # a.y = 0.5 a.u + 1 + t, b.y = 0.5 b.u; a.u = b.y, b.u = a.y.
    # Initialization Mode: a = 4/3, b = 2/3 (solved). Steps (a, then b, in
    # Gauss-Seidel order): a steps with b's last output, b with a's new one.
    path = str(strict[version])
    comps = {"a": (path, {"gain": 0.5, "offset": 1.0, "slope": 1.0}), "b": (path, {"gain": 0.5})}
    h = 0.125
    cols, master = _run(comps, ["a.y -> b.u", "b.y -> a.u"], 1.0, h, {"a": ["y"], "b": ["y"]}, engine=engine)
    a, b = cols["a.y"], cols["b.y"]
    assert len(a) == 9
    assert abs(a[0] - 4.0 / 3.0) <= 1e-9 and abs(b[0] - 2.0 / 3.0) <= 1e-9
    for k in range(1, 9):
        t = cols["time"][k]
        assert a[k] == 0.5 * b[k - 1] + 1.0 + 1.0 * t
        assert b[k] == 0.5 * a[k]
    notes = [n for n in master.notes if "algebraic loop" in n]
    assert len(notes) == 1 and "one-step delay" in notes[0] and "Initialization Mode" in notes[0]
    err = capsys.readouterr().err
    assert err.count("clockwork: note: algebraic loop") == 1


@pytest.mark.parametrize("engine", ENGINES)
def test_with_event_location_it_reads_the_clock(strict, engine):
    # The clock (pendulum and grasshopper escapement, events located) with
    # the strict FMU reading the pendulum's angle: every point, the angle.
    comps = {"pendulum": (str(fmu_file("Pendulum")), {"Q": 1000.0}),
             "escapement": (str(fmu_file("GrasshopperEscapement")), {"torque": 0.004, "phi_r": math.radians(2.0)}),
             "ft": (str(strict[2]), {})}
    links = ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w",
             "escapement.tau -> pendulum.tau_escapement", "pendulum.phi -> ft.u"]
    cols, master = _run(comps, links, 6.0, 0.05, {"pendulum": ["phi"], "ft": ["y"]}, engine=engine,
                        event_location=True)
    assert master.stats.events > 0
    assert cols["ft.y"] == cols["pendulum.phi"]
    assert cols["time"][-1] == 6.0


@pytest.mark.parametrize("engine", ENGINES)
def test_simulate_runs_a_scene_with_the_strict_fmu(strict, tmp_path, engine):
    scene = tmp_path / "s.toml"
    scene.write_text(f'''connections = ["osc.x -> ft.u"]
[scene]
title = "a chain through the strict FMU"
[components.osc]
fmu = "{test_fmu("TestOscillator")}"
[components.ft]
fmu = "{strict[3]}"
parameters = {{ gain = 2.0 }}
[experiment]
stop = 1.0
[master]
step = 0.01
engine = "{engine}"
[record]
outputs = ["osc.x", "ft.y"]
''')
    r = clockwork.simulate(str(scene))
    assert len(r) == 101
    assert list(r["ft.y"]) == [2.0 * x for x in r["osc.x"]]


def test_validate_says_how_a_loop_with_the_strict_fmu_is_handled(strict, tmp_path, capsys):
    scene = tmp_path / "loop.toml"
    scene.write_text(f'''connections = ["a.y -> b.u", "b.y -> a.u"]
[scene]
title = "a loop of two strict FMUs"
[components.a]
fmu = "{strict[2]}"
parameters = {{ gain = 0.5, offset = 1.0 }}
[components.b]
fmu = "{strict[3]}"
parameters = {{ gain = 0.5 }}
[experiment]
stop = 1.0
[master]
step = 0.125
''')
    code, out, _ = run_cli(capsys, ["validate", scene])
    assert code == 0
    (note,) = [line for line in out.splitlines() if "algebraic loop" in line]
    assert "solved in Initialization Mode, then broken by a one-step delay: a, b do not allow" in note


@pytest.mark.parametrize("settings", [{"iterations": 3}, {"richardson": True}, {"extrapolation": 2}],
                         ids=["strong coupling", "step doubling", "extrapolation"])
def test_rollbacks_and_input_polynomials_keep_the_sequence(strict, settings):
    # Steps repeated from a restored FMU state (strong coupling, step
    # doubling) and polynomial inputs, all without a forbidden get. Step
    # doubling and extrapolation: the strict FMU steps after its source and
    # shows its new value (it takes no input derivatives). Strong coupling
    # gives every dynamic instance its inputs at the step's start, as a line
    # to the last iterate's end where it can interpolate them: this one
    # cannot, so it shows the value at the step's start.
    comps = {"ft": (str(strict[2]), {}), "osc": (str(test_fmu("TestOscillator")), {"omega": 2.0})}
    cols, master = _run(comps, ["osc.x -> ft.u"], 1.0, 0.05, {"osc": ["x"], "ft": ["y"]}, **settings)
    x, y = cols["osc.x"], cols["ft.y"]
    assert cols["time"][-1] == 1.0 and y[0] == x[0]
    if "iterations" in settings:
        assert master.stats.coupling_iterations > 0
        assert y[1:] == x[:-1]
    else:
        assert y == x
