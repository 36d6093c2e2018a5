"""clockwork.simulate against fmpy.simulate_fmu: the same bits for a
Co-Simulation FMU alone at the same step, with and without inputs, on both
engines; fmpy's arguments mapped or refused in one line; wrong types refused
(docs/fmpy-migration.md)."""

from __future__ import annotations

import numpy as np
import pytest
from fmpy import simulate_fmu

import clockwork
from clockwork.engine import MasterSettings
from clockwork.errors import SceneError, UsageError
from cwtest import fmu_file, test_fmu

ENGINES = ["python", "compiled"]


def _same(a, b, names=None):
    assert a.dtype.names[0] == b.dtype.names[0] == "time"
    for n in names or a.dtype.names:
        assert a[n].dtype == b[n].dtype, n
        assert np.array_equal(a[n], b[n]), (n, a[n], b[n])
    assert len(a) == len(b)


@pytest.mark.parametrize("engine", ENGINES)
def test_an_fmu_alone_gives_fmpys_bits(engine):
    """TestDecay: its DefaultExperiment (step 0.1, tolerance 1e-3: the Euler steps it takes)."""
    f = test_fmu("TestDecay")
    _same(simulate_fmu(str(f)), clockwork.simulate(f, master={"engine": engine}))


@pytest.mark.parametrize("engine", ENGINES)
def test_a_long_run_at_another_step_gives_fmpys_bits(engine):
    """202 s at 0.01 s: 20200 steps, the chunked runs end on the grid (no step an ulp short)."""
    f = test_fmu("TestDecay")
    sig = np.array([(0.0, 0.0), (50.0, 1.0), (202.0, -1.0)], dtype=[("time", float), ("v", float)])
    a = simulate_fmu(str(f), stop_time=202, output_interval=0.01, input=sig)
    _same(a, clockwork.simulate(f, stop_time=202, step_size=0.01, input=sig, master={"engine": engine}))


@pytest.mark.parametrize("engine", ENGINES)
def test_an_input_array_drives_the_fmu_as_fmpys_does(engine):
    """A ramp, a step on the grid, one off it (a communication point there), the last value held."""
    f = test_fmu("TestDecay")
    sig = np.array([(0.0, 0.0), (0.35, 1.0), (0.5, 1.0), (0.5, -2.0), (0.55, 0.0), (0.55, 3.0), (0.8, 3.0)],
                   dtype=[("time", float), ("v", float)])
    a = simulate_fmu(str(f), input=sig)
    b = clockwork.simulate(f, input=sig, master={"engine": engine})
    _same(a, b)
    assert 0.55 in b["time"] and len(b) == 12
    assert not np.array_equal(b["x"], clockwork.simulate(f)["x"])  # the input reaches the FMU


def test_an_input_file_gives_what_the_array_gives(tmp_path):
    f = test_fmu("TestDecay")
    (tmp_path / "v.csv").write_text("time,v\n0,0\n0.35,1\n0.5,1\n0.5,-2\n0.8,3\n")
    sig = np.array([(0.0, 0.0), (0.35, 1.0), (0.5, 1.0), (0.5, -2.0), (0.8, 3.0)], dtype=[("time", float), ("v", float)])
    _same(clockwork.simulate(f, input=tmp_path / "v.csv"), clockwork.simulate(f, input=sig))
    _same(clockwork.simulate(f, input=str(tmp_path / "v.csv")), simulate_fmu(str(f), input=sig))


def test_start_stop_tolerance_start_values_and_output_map():
    f = test_fmu("TestDecay")
    kwargs = dict(start_time=0.5, stop_time=2.0, relative_tolerance=1e-4, start_values={"k": 2.0, "x0": 3.0},
                  output_interval=0.05, output=["x"])
    _same(simulate_fmu(str(f), **kwargs), clockwork.simulate(f, **kwargs))


def test_step_size_and_output_interval_together():
    """step_size is the master's step; output_interval how often to record (a multiple of it)."""
    f = test_fmu("TestDecay")
    every = clockwork.simulate(f, step_size=0.01)
    some = clockwork.simulate(f, step_size=0.01, output_interval=0.1)
    assert len(every) == 101 and len(some) == 11
    assert np.array_equal(every["x"][::10], some["x"])


def test_integer_and_boolean_outputs_have_fmpys_types():
    f = test_fmu("TestStair")
    a = simulate_fmu(str(f), stop_time=3)
    b = clockwork.simulate(f, stop_time=3)
    # fmpy's fields, in fmpy's order: by type (Real, then Integer, then Boolean)
    assert b.dtype == a.dtype == np.dtype([("time", "<f8"), ("level", "<f8"), ("counter", "<i4"),
                                           ("shifted", "<i4"), ("odd", "?")])
    _same(a, b, ["time", "counter", "level", "shifted", "odd"])


def test_a_system_keeps_instance_names():
    scene = clockwork.simulate(fmu_file("Pendulum").parent.parent / "scenarios" / "core_grasshopper.toml",
                               stop_time=0.5)
    assert scene.dtype.names == ("time", "pendulum.phi", "pendulum.w", "escapement.tau") and len(scene) == 11


def test_master_settings_apply():
    f = test_fmu("TestDecay")
    assert len(clockwork.simulate(f, master=MasterSettings(step=0.05))) == 21
    assert len(clockwork.simulate(f, master={"step": 0.25})) == 5
    b = clockwork.simulate(f, master=MasterSettings(engine="python"))
    _same(b, clockwork.simulate(f))


@pytest.mark.parametrize("kwargs, needle", [
    ({"solver": "Euler"}, "simulate(solver='Euler'): not supported (it is for Model Exchange FMUs)"),
    ({"timeout": 5}, "simulate(timeout=5): not supported"),
    ({"validate": False}, "simulate(validate=False): not supported"),
    ({"fmi_type": "ModelExchange"}, "simulate(fmi_type='ModelExchange')"),
    ({"set_input_derivatives": True}, "master={'extrapolation': 1}"),
    ({"debug_logging": True}, "simulate(debug_logging=True)"),
    ({"step_finished": print}, "simulate(step_finished="),
    ({"unknown_thing": 1}, "unexpected argument unknown_thing="),
])
def test_fmpys_other_arguments_are_refused_in_one_line(kwargs, needle):
    with pytest.raises(UsageError) as e:
        clockwork.simulate(test_fmu("TestDecay"), **kwargs)
    assert needle in str(e.value) and "\n" not in str(e.value)


def test_fmpys_other_arguments_at_their_defaults_pass():
    f = test_fmu("TestDecay")
    _same(clockwork.simulate(f), clockwork.simulate(f, validate=True, solver="CVode", fmi_type="CoSimulation",
                                                     timeout=None, debug_logging=False, set_stop_time=True,
                                                     remote_platform="auto"))


@pytest.mark.parametrize("kwargs, needle", [
    ({"stop_time": "10"}, "simulate(stop_time='10'): expected a finite number"),
    ({"start_time": True}, "simulate(start_time=True)"),
    ({"stop_time": float("inf")}, "simulate(stop_time=inf)"),
    ({"step_size": 0.0}, "simulate(step_size=0.0): expected a number > 0"),
    ({"start_values": [("k", 1)]}, "start_values"),
    ({"output": "x"}, "simulate(output='x'): expected a list of variable names"),
    ({"master": 3}, "simulate(master=3)"),
    ({"progress": "yes"}, "simulate(progress='yes')"),
    ({"input": [1, 2]}, "simulate(input=...): expected fmpy's structured array"),
    ({"step_size": 0.1, "master": {"step": 0.2}}, "step_size and master's step both given"),
])
def test_wrong_types_are_refused_in_one_line(kwargs, needle):
    with pytest.raises(UsageError) as e:
        clockwork.simulate(test_fmu("TestDecay"), **kwargs)
    assert needle in str(e.value)


def test_bad_filename_and_values_are_scene_errors(tmp_path):
    with pytest.raises(UsageError, match="expected the path"):
        clockwork.simulate(3)
    with pytest.raises(SceneError, match="no such FMU file"):
        clockwork.simulate(tmp_path / "none.fmu")
    with pytest.raises(SceneError, match="has no variable kk"):
        clockwork.simulate(test_fmu("TestDecay"), start_values={"kk": 1})
    with pytest.raises(SceneError, match="record.outputs"):
        clockwork.simulate(test_fmu("TestDecay"), output=["y"])


@pytest.mark.parametrize("signals, needle", [
    (np.array([(0.0, 1.0)], dtype=[("t", float), ("v", float)]), "the first field is 't': expected time"),
    (np.array([(0.0, 1.0)], dtype=[("time", float), ("w", float)]), "field 'w': no input of that name"),
    (np.array([(0.0, np.nan)], dtype=[("time", float), ("v", float)]), "field 'v': row 0: expected a finite"),
    (np.array([(1.0, 1.0), (0.0, 1.0)], dtype=[("time", float), ("v", float)]), "time 0.0 (sample 1) is before"),
])
def test_a_bad_input_array_is_one_line(signals, needle):
    with pytest.raises(UsageError) as e:
        clockwork.simulate(test_fmu("TestDecay"), input=signals)
    assert needle in str(e.value)
