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
    ({"stop_time": "10"}, "simulate(): stop_time = '10': expected a finite time in s"),
    ({"start_time": True}, "simulate(): start_time = True"),
    ({"stop_time": float("inf")}, "simulate(): stop_time = inf"),
    ({"step_size": 0.0}, "simulate(): step_size = 0.0: expected a number > 0"),
    ({"start_values": [("k", 1)]}, "start_values"),
    ({"output": "x"}, "simulate(): output = 'x': expected a list of variable names"),
    ({"master": 3}, "simulate(): master = 3"),
    ({"progress": "yes"}, "simulate(): progress = 'yes'"),
    ({"input": [1, 2]}, "simulate(): input = [1, 2]: expected fmpy's structured array"),
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
    with pytest.raises(SceneError, match=r"output\[1\]"):
        clockwork.simulate(test_fmu("TestDecay"), output=["x", "y"])


@pytest.mark.parametrize("signals, needle", [
    (np.array([(0.0, 1.0)], dtype=[("t", float), ("v", float)]), "the first field is 't': expected time"),
    (np.array([(0.0, 1.0)], dtype=[("time", float), ("w", float)]), "field 'w': no input of that name"),
    (np.array([(0.0, np.nan)], dtype=[("time", float), ("v", float)]), "field 'v': row 0: expected a finite"),
    (np.array([(1.0, 1.0), (0.0, 1.0)], dtype=[("time", float), ("v", float)]), "row 1: 0.0 s is before the row above"),
])
def test_a_bad_input_array_is_one_line(signals, needle):
    with pytest.raises(UsageError) as e:
        clockwork.simulate(test_fmu("TestDecay"), input=signals)
    assert needle in str(e.value)


# --- issue 37, class 3: values of every kind, checked where they enter ------------------------------------
#
# Every argument of simulate() is given values of kinds a caller may pass by
# mistake: one ClockworkError (a UsageError, or a SceneError for what only the
# FMU variable can judge) naming the argument, never a TypeError, ValueError
# or OverflowError from the text simulate() used to build.

import decimal  # noqa: E402
import fractions  # noqa: E402

from clockwork.errors import ClockworkError  # noqa: E402

ODD = {"None": None, "complex": 1 + 2j, "Decimal": decimal.Decimal("0.5"), "dict": {"a": 1}, "set": {1.0},
       "bytes": b"1", "object": object(), "datetime64": np.datetime64("2020-01-01"),
       "timedelta64": np.timedelta64(1, "s"), "huge": 10**400, "-huge": -10**400, "nan": float("nan"),
       "inf": float("inf"), "np.nan": np.float64("nan"), "bool": True, "np.bool_": np.bool_(True),
       "array": np.array([0.5]), "2-D array": np.zeros((2, 2)), "list": [0.5], "text": "abc",
       "function": len, "10**5000": 10**5000}


def _one_error(call, *needles):
    with pytest.raises(ClockworkError) as e:
        call()
    text = str(e.value)
    assert "\n" not in text
    for n in needles:
        assert n in text, (n, text)
    return text


TIMES = ["start_time", "stop_time", "step_size", "relative_tolerance", "output_interval"]


@pytest.mark.parametrize("arg", TIMES)
@pytest.mark.parametrize("kind", [k for k in ODD if k != "None"])
def test_an_odd_time_or_tolerance_is_one_line_naming_it(arg, kind):
    _one_error(lambda: clockwork.simulate(test_fmu("TestDecay"), **{arg: ODD[kind]}), f"simulate(): {arg} = ")


@pytest.mark.parametrize("kind", [k for k in ODD if k not in ("list", "array", "text")])
def test_an_odd_start_value_is_one_line_naming_it(kind):
    """A Real parameter: what TOML has no kind for is refused as the
    argument is read; a bool, a NaN, an infinity, 10**400 or an array by
    the variable (k is a scalar Real)."""
    _one_error(lambda: clockwork.simulate(test_fmu("TestDecay"), start_values={"k": ODD[kind]}),
               "start_values['k']")


@pytest.mark.parametrize("name, value", [
    ("p_int", 1.5), ("p_int", np.float64(2.0)), ("p_int", 2**40), ("p_int", 10**400), ("p_int", True),
    ("p_int", np.array([2])), ("p_bool", 1), ("p_bool", np.int64(0)), ("p_bool", 1.0), ("p_bool", "yes"),
    ("p_enum", 7), ("p_enum", "medium"), ("p_enum", 1.0), ("p_str", 3), ("p_str", np.float64(1)),
    ("p_real", "1.5 furlong"), ("p_real", [1.0, 2.0]), ("gain.k", None), ("p_real", np.datetime64("2020")),
])
def test_a_start_value_of_the_wrong_type_or_range_names_it(name, value):
    _one_error(lambda: clockwork.simulate(test_fmu("TestTypes"), start_values={name: value}),
               f"start_values[{name!r}]")


@pytest.mark.parametrize("key, value", [
    ("step", None), ("step", 1 + 2j), ("step", decimal.Decimal("0.1")), ("step", np.array([0.1])),
    ("step", float("nan")), ("step", True), ("step", 10**400), ("iterations", 10**400), ("iterations", 1.5),
    ("iterations", np.float64(2)), ("order", {"a": 1}), ("order", {"jacobi"}), ("engine", ["python"]),
    ("engine", b"python"), ("tolerance", float("inf")), ("event_location", 1), ("threads", 10**30),
    ("extrapolation", np.array([1])), ("no_such_setting", 1),
])
def test_an_odd_master_setting_is_one_line_naming_it(key, value):
    _one_error(lambda: clockwork.simulate(test_fmu("TestDecay"), master={key: value}), key)


@pytest.mark.parametrize("output", [5, 5.0, None.__class__, "x", b"x", {"x": 1}, [5], ["x", None], [b"x"],
                                    np.array([["x"]]), iter([1, 2])])
def test_an_odd_output_is_one_line_naming_it(output):
    if output is None.__class__:
        output = object()
    _one_error(lambda: clockwork.simulate(test_fmu("TestDecay"), output=output), "output")


GOOD_NUMBERS = [np.float64, np.float32, np.int64, np.int32, np.uint8, int, fractions.Fraction]


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("kind", GOOD_NUMBERS, ids=lambda k: k.__name__)
def test_numbers_of_any_real_type_give_the_plain_values_result(engine, kind):
    """numpy's scalars, a 0-d array, Python's int and fractions: the result
    of the plain float (each value is a whole number, exact in every type)."""
    f = test_fmu("TestDecay")
    plain = clockwork.simulate(f, start_time=0.0, stop_time=2.0, step_size=0.25, relative_tolerance=1.0,
                               start_values={"k": 2.0, "x0": 3.0}, master={"engine": engine, "iterations": 0})
    odd = clockwork.simulate(f, start_time=kind(0), stop_time=kind(2), step_size=fractions.Fraction(1, 4),
                             relative_tolerance=kind(1), start_values={"k": kind(2), "x0": kind(3)},
                             master={"engine": engine, "iterations": kind(0) if issubclass(kind, (int, np.integer))
                                     else 0})
    _same(plain, odd)
    _same(odd, simulate_fmu(str(f), start_time=0.0, stop_time=2.0, output_interval=0.25, relative_tolerance=1.0,
                            start_values={"k": 2.0, "x0": 3.0}))


@pytest.mark.parametrize("engine", ENGINES)
def test_start_values_of_every_type_take_numpy_and_python_kinds_alike(engine):
    """Integer, Boolean and Enumeration parameters given numpy's scalars
    (np.int64, np.bool_) give what Python's int and bool give."""
    f = test_fmu("TestTypes")
    plain = clockwork.simulate(f, start_values={"p_int": 7, "p_bool": True, "p_enum": 3, "p_real": 2.5,
                                                "gain.k": 2.0}, master={"engine": engine})
    odd = clockwork.simulate(f, start_values={"p_int": np.int32(7), "p_bool": np.bool_(True), "p_enum": np.uint8(3),
                                              "p_real": np.float64(2.5), "gain.k": np.int64(2)},
                             master={"engine": engine})
    _same(plain, odd)
    assert not np.array_equal(plain["y_real"], clockwork.simulate(f)["y_real"])  # the values reached the FMU


def test_a_master_settings_object_with_numpy_numbers_applies():
    f = test_fmu("TestDecay")
    _same(clockwork.simulate(f, master=MasterSettings(step=np.float64(0.25), iterations=np.int64(0))),
          clockwork.simulate(f, master={"step": 0.25}))


# --- input arrays: every field checked for what it holds --------------------------------------------------

def _signals(time, v=None, time_dtype=None, v_dtype=float):
    time = np.asarray(time, dtype=time_dtype)
    v = np.zeros(len(time)) if v is None else v
    a = np.empty(len(time), dtype=[("time", time.dtype, time.shape[1:]), ("v", v_dtype)])
    a["time"], a["v"] = time, v
    return a


BAD_SIGNALS = {
    "text time": (lambda: _signals(["0", "1"]), "field 'time'"),
    "datetime time": (lambda: _signals(np.array(["2020-01-01", "2020-01-02"], dtype="datetime64[D]")), "'time'"),
    "timedelta time": (lambda: _signals(np.array([0, 1], dtype="timedelta64[s]")), "'time'"),
    "object time": (lambda: _signals([0.0, 1.0], time_dtype=object), "'time'"),
    "bool time": (lambda: _signals([False, True]), "'time'"),
    "complex time": (lambda: _signals([0j, 1j]), "'time'"),
    "nan time": (lambda: _signals([0.0, np.nan]), "row 1: expected a finite time"),
    "inf time": (lambda: _signals([0.0, np.inf]), "row 1: expected a finite time"),
    "time going back": (lambda: _signals([0.0, 0.5, 0.2]), "row 2: 0.2 s is before"),
    "no rows": (lambda: _signals(np.zeros(0)), "no rows"),
    "time of arrays": (lambda: _signals(np.zeros((2, 2))), "shape (2,)"),
    "text input": (lambda: _signals([0.0, 1.0], ["a", "b"], v_dtype="U3"), "field 'v'"),
    "object input": (lambda: _signals([0.0, 1.0], [None, 1.0], v_dtype=object), "field 'v'"),
    "complex input": (lambda: _signals([0.0, 1.0], [1j, 1j], v_dtype=complex), "field 'v'"),
    "input of arrays": (lambda: _signals([0.0, 1.0], np.zeros((2, 3)), v_dtype=(float, 3)), "field 'v'"),
    "inf input": (lambda: _signals([0.0, 1.0], [0.0, np.inf]), "row 1: expected a finite number"),
    "no time": (lambda: np.zeros(2, dtype=[("v", float), ("time", float)]), "expected time"),
    "2-D": (lambda: np.zeros((2, 2), dtype=[("time", float), ("v", float)]), "input = "),
    "not structured": (lambda: np.zeros((2, 2)), "input = "),
    "no fields but time": (lambda: np.zeros(0, dtype=[("time", float)]), "no rows"),
}


@pytest.mark.parametrize("case", list(BAD_SIGNALS))
def test_a_bad_input_array_field_is_one_usage_error(case):
    make, needle = BAD_SIGNALS[case]
    with pytest.raises(UsageError) as e:
        clockwork.simulate(test_fmu("TestDecay"), input=make())
    assert needle in str(e.value) and "input" in str(e.value) and "\n" not in str(e.value), str(e.value)


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("time_dtype", [np.int64, np.int32, np.uint16, np.float32])
def test_input_times_of_any_real_dtype_drive_the_fmu_as_floats_do(engine, time_dtype):
    f = test_fmu("TestDecay")
    plain = _signals([0.0, 1.0, 1.0, 2.0], [0.0, 1.0, -1.0, 2.0])
    odd = _signals(np.array([0, 1, 1, 2], dtype=time_dtype), np.array([0, 1, -1, 2], dtype=np.int16),
                   v_dtype=np.int16)
    kw = dict(stop_time=3.0, step_size=0.25, master={"engine": engine})
    _same(clockwork.simulate(f, input=plain, **kw), clockwork.simulate(f, input=odd, **kw))
    _same(clockwork.simulate(f, input=odd, **kw), simulate_fmu(str(f), stop_time=3.0, output_interval=0.25,
                                                                input=plain))


# --- issue 37, class 4: what is accepted does what fmpy does --------------------------------------------------

@pytest.mark.parametrize("engine", ENGINES)
def test_an_empty_output_list_gives_time_alone_as_fmpy(engine):
    f = test_fmu("TestDecay")
    got = clockwork.simulate(f, output=[], master={"engine": engine})
    assert got.dtype.names == ("time",) and len(got) == 11
    _same(got, simulate_fmu(str(f), output=[]))
    assert np.array_equal(got["time"], clockwork.simulate(f)["time"])


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("how", ["tuple", "generator", "numpy", "set", "dict keys", "twice", "map"])
def test_output_names_in_any_iterable_give_the_lists_result(engine, how):
    f = test_fmu("TestTypes")
    names = ["y_real", "y_int"]
    given = {"tuple": lambda: tuple(names), "generator": lambda: (n for n in names),
             "numpy": lambda: np.array(names), "set": lambda: set(names),
             "dict keys": lambda: dict.fromkeys(names).keys(),
             "twice": lambda: names + names[::-1], "map": lambda: map(str, names)}[how]()
    got = clockwork.simulate(f, output=given, master={"engine": engine})
    assert sorted(got.dtype.names) == ["time", "y_int", "y_real"] and len(got) > 1
    ref = simulate_fmu(str(f), output=names)
    for n in ref.dtype.names:
        assert got[n].dtype == ref[n].dtype and np.array_equal(got[n], ref[n]), n


def _renamed(fmu, folder, old: str, new: str):
    """A copy of `fmu` whose variable `old` is called `new` (the binary
    knows it by its value reference)."""
    import zipfile

    out = folder / f"{fmu.stem}_{len(list(folder.iterdir()))}.fmu"
    with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(out, "w") as dst:
        for item in src.infolist():
            data = src.read(item.filename)
            if item.filename == "modelDescription.xml":
                text = data.decode()
                assert text.count(f'name="{old}"') == 1
                data = text.replace(f'name="{old}"', f'name="{new}"').encode()
            dst.writestr(item, data)
    return out


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("name", ["experiment.stop", "experiment.start", "master.step", "record.interval",
                                  "scene.title", "master.engine", "analysis.kind", "TestDecay.k"])
def test_a_start_value_named_like_a_setting_sets_the_variable(tmp_path, engine, name):
    """An FMU parameter named experiment.stop (FMI names may hold dots) is
    the parameter: the run's stop time, step and recording stay as they
    were; fmpy's numbers."""
    f = _renamed(test_fmu("TestDecay"), tmp_path, "k", name)
    got = clockwork.simulate(f, start_values={name: 0.5}, master={"engine": engine})
    assert len(got) == 11 and got["time"][-1] == 1.0
    _same(got, simulate_fmu(str(f), start_values={name: 0.5}))
    assert not np.array_equal(got["x"], clockwork.simulate(f)["x"])  # it reached the FMU


def test_master_settings_never_reach_start_values():
    """A master key is a master setting, whatever the FMU's variables are called."""
    f = test_fmu("TestDecay")
    with pytest.raises(SceneError) as e:
        clockwork.simulate(f, master={"k": 2.0})
    assert "master['k']" in str(e.value) or "master.k" in str(e.value)


def test_a_stop_before_the_start_is_one_line_naming_stop_time():
    f = test_fmu("TestDecay")
    for start, stop in ((1.0, 0.5), (0.5, 0.5)):
        _one_error(lambda: clockwork.simulate(f, start_time=start, stop_time=stop), "stop_time")
    _one_error(lambda: clockwork.simulate(f, start_time=5.0), "start_time = 5: expected a time < experiment.stop (1 s)")
    _one_error(lambda: clockwork.simulate(f, output=["x", "nothing"]), "output[1]")
    _one_error(lambda: clockwork.simulate(f, start_values={"nothing": 1.0}), "start_values['nothing']")


@pytest.mark.parametrize("engine", ENGINES)
def test_an_fmu_whose_only_output_has_no_elements_gives_its_rows(engine):
    """fmpy's result: a row per communication point, the output a field of shape (0,).
    The FMU: FMI 3.0 Linear whose only output, y, has a Dimension of size 0
    (fmi3_linear.empty_output_description)."""
    f = test_fmu("fmi3/Empty")
    for output in (None, ["y"]):
        got = clockwork.simulate(f, output=output, master={"engine": engine})
        assert got.dtype.names == ("time", "y") and got.dtype["y"].shape == (0,)
        assert len(got) == 21 and got["time"][-1] == 2.0


@pytest.mark.parametrize("engine", ENGINES)
def test_a_step_longer_than_the_run_ends_at_the_stop_as_fmpy(engine):
    f = test_fmu("TestDecay")
    for kw in ({"step_size": 5.0}, {"output_interval": 7.0}, {"stop_time": 1e-11}):
        ref = simulate_fmu(str(f), stop_time=kw.get("stop_time"), output_interval=kw.get("output_interval",
                                                                                             kw.get("step_size")))
        _same(clockwork.simulate(f, **kw, master={"engine": engine}), ref)


@pytest.mark.parametrize("kw, needle", [
    ({"step_size": 0.1, "output_interval": 0.15}, "output_interval = 0.15: expected a whole multiple"),
    ({"step_size": 0.1, "output_interval": 0.05}, "output_interval = 0.05: expected a whole multiple"),
    ({"master": {"step": 0.25}, "output_interval": 0.3}, "output_interval = 0.3"),
    ({"stop_time": 1e-300}, "stop_time: expected stop more than"),
    ({"start_time": 3.0, "stop_time": 3.0}, "stop_time"),
])
def test_an_interval_off_the_step_or_a_span_too_short_to_step_is_one_line(kw, needle):
    """fmpy records on its own grid: an interval that is not a whole number
    of steps (rounded to one before) or a span no step can cover (one row
    before) is refused."""
    _one_error(lambda: clockwork.simulate(test_fmu("TestDecay"), **kw), needle)


@pytest.mark.parametrize("engine", ENGINES)
def test_fmi3_array_start_values_take_numpy_arrays_lists_and_tuples_as_fmpy(engine):
    """x0 (3) and A (3x3) given as numpy arrays, tuples or nested lists: one
    result, fmpy's; a wrong shape or an object array is one line naming it."""
    f = test_fmu("fmi3/Linear")
    A = -np.diag([1.0, 2.0, 0.5])
    results = [clockwork.simulate(f, start_values={"x0": x0, "A": a}, master={"engine": engine})
               for x0, a in ((np.array([1.0, 2.0, 3.0]), A), ((1, 2, 3), A.tolist()),
                             ([np.float64(1), np.int64(2), 3.0], tuple(map(tuple, A))))]
    for r in results[1:]:
        _same(results[0], r)
    assert results[0]["x"][0].tolist() == [1.0, 2.0, 3.0]  # the values reached the FMU
    _same(results[0], simulate_fmu(str(f), start_values={"x0": np.array([1.0, 2.0, 3.0]), "A": A.ravel()},  # flat
                                   output_interval=0.1), ["time", "x", "y"])
    for bad in ({"x0": np.array([1.0, 2.0])}, {"A": -np.eye(2)}, {"x0": np.array([1, 2, 3], dtype=object)},
                {"x0": np.array(["a", "b", "c"])}, {"x0": 1.0}, {"A": [[1.0] * 3] * 2 + [[1.0] * 2]}):
        name = next(iter(bad))
        _one_error(lambda: clockwork.simulate(f, start_values=bad), f"start_values[{name!r}]")


def test_progress_takes_numpys_bool():
    f = test_fmu("TestDecay")
    _same(clockwork.simulate(f, progress=np.bool_(False)), clockwork.simulate(f))


@pytest.mark.parametrize("engine", ENGINES)
def test_a_scene_takes_outputs_its_plots_do_not_draw_and_numpy_start_values(engine):
    """A scene's plots are not drawn by simulate(): an output list without
    the columns they name (or empty) records what it names; a system's
    start value is "instance.variable", of any real type."""
    scene = fmu_file("Pendulum").parent.parent / "scenarios" / "core_grasshopper.toml"
    kw = dict(stop_time=0.5, master={"engine": engine})
    assert clockwork.simulate(scene, output=[], **kw).dtype.names == ("time",)
    assert clockwork.simulate(scene, output=("escapement.tau",), **kw).dtype.names == ("time", "escapement.tau")
    a = clockwork.simulate(scene, start_values={"pendulum.Q": np.float64(500)}, **kw)
    _same(a, clockwork.simulate(scene, start_values={"pendulum.Q": 500}, **kw))
    assert not np.array_equal(a["pendulum.phi"], clockwork.simulate(scene, **kw)["pendulum.phi"])
    text = _one_error(lambda: clockwork.simulate(scene, start_values={"experiment.stop": 1.0}, **kw),
                      "start_values['experiment.stop']: no component named experiment")
    assert "did you mean experiment" not in text


@pytest.fixture(scope="module")
def alltypes():
    return test_fmu("fmi3/AllTypes")


FMI3_BAD = {"Float32": [1e39, "x", np.float64(1e39), None], "Float64": [[1.0], 1 + 1j, decimal.Decimal(1)],
            "Int8": [200, np.int16(-129), 1.5, np.float64(1.0)], "UInt8": [-1, 256, np.int64(-1)],
            "Int16": [2**15, np.float32(1)], "UInt16": [2**16, True], "Int32": [2**31, -2**31 - 1],
            "UInt32": [-1, 2**32], "Int64": [2**63, -2**63 - 1, 10**400], "UInt64": [-1, 2**64, np.int8(-1)],
            "Boolean": [1, np.int64(1), "true", 1.0], "String": [3, np.int64(3), b"s", None],
            "Binary": ["xyz", 3, b"\x00"], "Enumeration": [1.0, 99, np.float64(1)]}


@pytest.mark.parametrize("kind, bad", [(k, v) for k, vs in FMI3_BAD.items() for v in vs],
                         ids=[f"{k}-{v!r}"[:40] for k, vs in FMI3_BAD.items() for v in vs])
def test_an_fmi3_start_value_is_checked_against_its_type_and_range(alltypes, kind, bad):
    _one_error(lambda: clockwork.simulate(alltypes, start_values={f"p_{kind}": bad}), f"start_values['p_{kind}']")


@pytest.mark.parametrize("engine", ENGINES)
def test_fmi3_start_values_of_numpys_types_give_pythons_result(alltypes, engine):
    plain = {"p_Float32": 1.5, "p_Int8": -100, "p_UInt16": 65535, "p_Int64": -2**63, "p_UInt64": 2**64 - 1,
             "p_Boolean": True, "p_String": "s", "p_Enumeration": 2}
    odd = {"p_Float32": np.float32(1.5), "p_Int8": np.int8(-100), "p_UInt16": np.uint16(65535),
           "p_Int64": np.int64(-2**63), "p_UInt64": np.uint64(2**64 - 1), "p_Boolean": np.bool_(True),
           "p_String": np.str_("s"), "p_Enumeration": np.int32(2)}
    kw = dict(stop_time=0.3, master={"engine": engine})
    _same(clockwork.simulate(alltypes, start_values=plain, **kw), clockwork.simulate(alltypes, start_values=odd, **kw))


@pytest.mark.parametrize("field, value", [("order", {"a"}), ("step", np.array([0.1, 0.2])), ("step", "x"),
                                          ("iterations", 10**400), ("engine", b"python"), ("tolerance", 1j)])
def test_a_master_settings_object_changed_after_its_checks_is_checked_again(field, value):
    s = MasterSettings()
    setattr(s, field, value)
    _one_error(lambda: clockwork.simulate(test_fmu("TestDecay"), master=s), field)


@pytest.mark.parametrize("kw", [{"start_values": {"k" * 100_000: 1.0}}, {"master": {"k" * 100_000: 1.0}},
                                {"output": ["k" * 100_000]}, {"start_values": {"k": "1" * 100_000}}])
def test_a_huge_name_or_value_gives_a_short_line(kw):
    assert len(_one_error(lambda: clockwork.simulate(test_fmu("TestDecay"), **kw))) < 1000
    scene = fmu_file("Pendulum").parent.parent / "scenarios" / "core_grasshopper.toml"
    assert len(_one_error(lambda: clockwork.simulate(scene, stop_time=0.1, **kw))) < 1000  # a system


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("kw", [{"output_interval": 0.3}, {"step_size": 0.3},
                                {"start_time": 0.25, "stop_time": 1.3, "output_interval": 0.2},
                                {"output_interval": 0.25, "stop_time": 0.5}, {"step_size": np.float32(0.5)}])
def test_a_step_that_does_not_divide_the_span_ends_at_the_stop_as_fmpy(engine, kw):
    f = test_fmu("TestDecay")
    ref = dict(kw)
    if "step_size" in ref:
        ref["output_interval"] = float(ref.pop("step_size"))
    _same(clockwork.simulate(f, **kw, master={"engine": engine}), simulate_fmu(str(f), **ref))


# --- hostile objects: what they raise while simulate() looks at them is a refusal (audit of issue 37) --------
#
# A float or int subclass whose __float__/__int__ raises, a str subclass
# whose __str__ lies, a path-like whose __fspath__ fails or gives bytes, an
# iterable or mapping that raises when read, an array's __eq__, a masked
# value: one ClockworkError naming the argument, never the object's own
# exception (before: RuntimeError, TypeError, ValueError from inside).

class _FloatRaises(float):
    def __float__(self):
        raise RuntimeError("boom")


class _IntRaises(int):
    def __int__(self):
        raise RuntimeError("boom")

    def __index__(self):
        raise RuntimeError("boom")


class _IntTypeError(int):
    def __int__(self):
        raise TypeError("no")


class _StrLies(str):
    def __str__(self):
        return 5


class _EqAll(str):
    def __eq__(self, other):
        return True

    def __hash__(self):
        return 1


class _FsRaises:
    def __fspath__(self):
        raise RuntimeError("boom")


class _FsBytes:
    def __init__(self, path):
        self.path = path

    def __fspath__(self):
        return bytes(self.path)


class _IterRaises:
    def __iter__(self):
        raise RuntimeError("boom")


class _ItemsRaise(dict):
    def items(self):
        raise RuntimeError("boom")


class _ArrayEq:
    def __eq__(self, other):
        return np.array([True, False])


HOSTILE = {
    "start_time=float raising": (dict(start_time=_FloatRaises(0.0)), "start_time"),
    "stop_time=float raising": (dict(stop_time=_FloatRaises(1.0)), "stop_time"),
    "step_size=float raising": (dict(step_size=_FloatRaises(0.1)), "step_size"),
    "start value float raising": (dict(start_values={"k": _FloatRaises(2.0)}), "start_values['k']"),
    "start value int raising": (dict(start_values={"k": _IntRaises(2)}), "start_values['k']"),
    "start value int TypeError": (dict(start_values={"k": _IntTypeError(2)}), "start_values['k']"),
    "start value list of them": (dict(start_values={"k": [_FloatRaises(1.0)]}), "start_values['k']"),
    "master iterations int raising": (dict(master={"iterations": _IntRaises(1)}), "master"),
    "master step float raising": (dict(master={"step": _FloatRaises(0.1)}), "master"),
    "start values items raising": (dict(start_values=_ItemsRaise(k=1.0)), "start_values"),
    "output iter raising": (dict(output=_IterRaises()), "output"),
    "output generator raising": (dict(output=(1 / 0 for _ in range(1))), "output"),
    "filename fspath raising": (dict(filename=_FsRaises()), "filename"),
    "filename fspath bytes": (dict(filename="bytes"), "filename"),
    "input fspath raising": (dict(input=_FsRaises()), "input"),
    "fmi_type array": (dict(fmi_type=np.array(["a", "b"])), "fmi_type"),
    "fmi_type eq array": (dict(fmi_type=_ArrayEq()), "fmi_type"),
    "masked start value": (dict(start_values={"k": np.ma.masked}), "start_values['k']"),
    "masked array start value": (dict(start_values={"k": np.ma.array([1.0], mask=[True])}), "start_values['k']"),
    "masked master step": (dict(master={"step": np.ma.masked}), "master"),
    "masked input row": (dict(input=np.ma.array(np.array([(0.0, 1.0), (0.5, 2.0)],
                                                         dtype=[("time", float), ("v", float)]),
                                                mask=[(False, False), (False, True)])), "input"),
}


@pytest.mark.parametrize("case", list(HOSTILE))
def test_a_hostile_object_is_one_line_naming_the_argument(case):
    kwargs, needle = HOSTILE[case]
    kwargs = dict(kwargs)
    f = test_fmu("TestDecay")
    if kwargs.get("filename") == "bytes":
        kwargs["filename"] = _FsBytes(f)
    kwargs.setdefault("filename", f)
    _one_error(lambda: clockwork.simulate(**kwargs), needle)


@pytest.mark.parametrize("engine", ENGINES)
def test_str_subclasses_are_their_characters(engine):
    """A str subclass (as a name, a key, a value, a path) is its characters:
    its own __str__, __eq__ and __hash__ are not asked (before: a __str__
    that returns no str raised TypeError; an __eq__ true for all matched
    no variable)."""
    f = test_fmu("TestDecay")
    plain = clockwork.simulate(f, start_values={"k": 2.0, "x0": "3"}, output=["x"], master={"engine": engine})
    odd = clockwork.simulate(_StrLies(str(f)), start_values={_StrLies("k"): 2.0, _EqAll("x0"): _StrLies("3")},
                             output=[_StrLies("x")], master={_StrLies("engine"): _StrLies(engine)})
    _same(plain, odd)
    _same(plain, simulate_fmu(str(f), start_values={"k": 2.0, "x0": 3.0}, output=["x"]))


def test_an_unmasked_masked_array_is_its_data():
    f = test_fmu("TestDecay")
    sig = np.array([(0.0, 0.0), (0.35, 1.0), (0.8, 3.0)], dtype=[("time", float), ("v", float)])
    _same(clockwork.simulate(f, input=sig, start_values={"k": 2.0}),
          clockwork.simulate(f, input=np.ma.array(sig), start_values={"k": np.ma.array(2.0)}))


def test_fmpys_bool_defaults_take_numpys_bool():
    f = test_fmu("TestDecay")
    _same(clockwork.simulate(f), clockwork.simulate(f, validate=np.True_, debug_logging=np.False_))


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("interval, stop, rows", [(0.3, 1.0, [0, 3, 6, 9, 10]), (0.2, 0.5, [0, 2, 4, 5]),
                                                  (10.0, 1.0, [0, 10]), (0.5, 1.0, [0, 5, 10])])
def test_an_output_interval_off_the_stop_still_ends_at_the_stop_as_fmpy(engine, interval, stop, rows):
    """step_size with an output_interval the span is no multiple of: the
    rows of the interval, then the stop, as fmpy's result always ends there
    (before: the stop was left out, and an interval longer than the span
    gave the start alone)."""
    f = test_fmu("TestDecay")
    every = clockwork.simulate(f, step_size=0.1, stop_time=stop, master={"engine": engine})
    some = clockwork.simulate(f, step_size=0.1, stop_time=stop, output_interval=interval, master={"engine": engine})
    _same(every[rows], some)
    assert some["time"][-1] == simulate_fmu(str(f), stop_time=stop, output_interval=interval)["time"][-1] == stop


@pytest.fixture(scope="module")
def linear():
    return test_fmu("fmi3/Linear")


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("dtype", ["f8", "f4", ">i4", "u1"])
def test_an_fmi3_array_input_field_drives_the_array_as_fmpy(linear, engine, dtype):
    """fmpy's layout for an FMI 3.0 array input, a field u of shape (2,):
    a column per element, fmpy's bits (before: refused as a field of
    shape (2,)); its element columns u[1], u[0] in any order the same."""
    u = np.array([(0.0, [1, 2]), (0.55, [3, 4]), (1.0, [0, 5])], dtype=[("time", "f8"), ("u", dtype, (2,))])
    b = clockwork.simulate(linear, input=u, master={"engine": engine})
    a = simulate_fmu(str(linear), input=u)
    _same(a, b, a.dtype.names)
    assert not np.array_equal(b["y"], clockwork.simulate(linear)["y"])  # the input reaches the FMU
    split = np.array([(t, v[1], v[0]) for t, v in u.tolist()], dtype=[("time", "f8"), ("u[1]", "f8"), ("u[0]", "f8")])
    _same(b, clockwork.simulate(linear, input=split, master={"engine": engine}))


@pytest.mark.parametrize("fields, rows, needle", [
    ([("u[1]", "f8")], [(0.0, 1.0)], "Linear.u[0] is missing"),
    ([("u[0]", "f8")], [(0.0, 1.0)], "Linear.u[1] is missing"),
    ([("u", "f8", (3,))], [(0.0, [1.0, 2.0, 3.0])], "field 'u': a field of shape (3,)"),
    ([("u", "f8", (2, 1))], [(0.0, [[1.0], [2.0]])], "u is of shape (2,)"),
    ([("w", "f8", (2,))], [(0.0, [1.0, 2.0])], "w is a scalar"),
    ([("zz", "f8", (2,))], [(0.0, [1.0, 2.0])], "zz names no variable"),
    ([("u", "f8", (0,))], [(0.0, [])], "field 'u'"),
    ([("u", "U3", (2,))], [(0.0, ["a", "b"])], "field 'u'"),
])
def test_part_of_an_fmi3_array_input_is_refused_before_the_run(linear, fields, rows, needle):
    """An FMI 3.0 array is set whole: columns for some of its elements, or
    a field of another shape, are one UsageError before the run (before:
    u[1] alone passed the checks and failed the run in fmi3SetFloat64)."""
    u = np.array(rows, dtype=[("time", "f8"), *fields])
    text = _one_error(lambda: clockwork.simulate(linear, input=u), "simulate(input=...)", needle)
    assert "fmi3Set" not in text


def test_validate_refuses_an_input_file_with_part_of_an_array(linear, tmp_path):
    """What run would fail on, validate refuses (issue 37, class 7): exit 2, one line."""
    import subprocess
    import sys

    (tmp_path / "u.csv").write_text("time,u[1]\n0,1\n0.5,2\n")
    p = subprocess.run([sys.executable, "-m", "clockwork", "validate", str(linear), "--input", str(tmp_path / "u.csv")],
                       capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert p.returncode == 2 and "Linear.u[0] is missing" in p.stderr and len(p.stderr.splitlines()) == 1, p.stderr


@pytest.mark.parametrize("output", ["repeat", "count", "cycle"])
def test_an_endless_output_iterator_is_one_line_not_a_hang(output):
    """An endless iterator of names (or of anything) is refused after at
    most MAX_OUTPUT_NAMES names (before: read until memory ran out; fmpy
    hangs the same way). The names are read one at a time, never by len()."""
    import itertools

    it = {"repeat": lambda: itertools.repeat("x"), "count": itertools.count,
          "cycle": lambda: itertools.cycle(["x", "k"])}[output]()
    _one_error(lambda: clockwork.simulate(test_fmu("TestDecay"), output=it), "output")


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("dtype", [np.float64, np.float32, np.int64, np.uint8])
def test_times_given_as_0d_arrays_give_the_plain_values_result(engine, dtype):
    """np.array(2.0) for a time, a step or a tolerance, as fmpy takes it
    (start values took 0-d arrays already; before: refused)."""
    f = test_fmu("TestDecay")
    kw = dict(start_time=0.0, stop_time=2.0, step_size=0.25, relative_tolerance=1.0)
    plain = clockwork.simulate(f, **kw, master={"engine": engine})
    _same(plain, clockwork.simulate(f, **{k: np.array(v, dtype=dtype) if v != 0.25 else np.array(v) for k, v in
                                           kw.items()}, master={"engine": engine}))
    _same(clockwork.simulate(f, output_interval=np.array(0.25), stop_time=np.array(2)),
          simulate_fmu(str(f), output_interval=np.array(0.25), stop_time=np.array(2)))
    for bad in (np.array(True), np.array(1 + 2j), np.array("1"), np.array(np.nan), np.ma.masked, np.array(-1.0)):
        _one_error(lambda: clockwork.simulate(f, step_size=bad), "step_size")


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("output, fields", [
    (["y", "y[0]"], ("time", "y")), (["y[0]", "y"], ("time", "y")), (["y[1]", "y", "x[2]"], ("time", "y", "x[2]")),
    (["Linear.y", "y[1]"], ("time", "y")),
])
def test_an_element_of_an_array_also_asked_whole_is_in_the_whole_as_fmpy(linear, engine, output, fields):
    """fmpy records y for ["y", "y[0]"]; clockwork refused it ("Linear.y[0]
    is listed twice"). The whole array's field, fmpy's bits."""
    b = clockwork.simulate(linear, output=output, master={"engine": engine})
    assert b.dtype.names == fields
    _same(simulate_fmu(str(linear), output=["y"]), b, ["time", "y"])


def test_a_connected_input_set_by_the_caller_is_named_as_the_caller_set_it(tmp_path, capsys):
    """An input that a connection drives and a start value or --set also
    sets: the line named the scene key components.<c>.parameters.<v>, which
    the caller never wrote, instead of what they did write."""
    from cwtest import CLOCK_SCENE, fmu_file, run_cli

    from clockwork.errors import SceneError

    fmu_file("Pendulum")
    scene = tmp_path / "clock.toml"
    scene.write_text(CLOCK_SCENE.format(stop=0.2, sweep=""))
    with pytest.raises(SceneError, match=r"also set in start_values\['pendulum.tau_escapement'\]$"):
        clockwork.simulate(scene, start_values={"pendulum.tau_escapement": 0.1})
    rc, _, err = run_cli(capsys, ["validate", scene, "--set", "pendulum.tau_escapement=0.1"])
    assert rc == 2 and err.rstrip().endswith("also set in --set pendulum.tau_escapement"), err


@pytest.mark.parametrize("kwargs, named", [
    ({"step_size": 1e-300}, "step_size"),
    ({"output_interval": 1e-300}, "output_interval"),  # the step when no step_size: named as given
    ({"step_size": 1e-13, "output_interval": 0.1}, "step_size"),
    ({"master": {"step": 1e-300}}, "master['step']"),
])
def test_a_step_below_the_smallest_is_named_as_the_caller_gave_it(kwargs, named):
    from clockwork.errors import SceneError

    with pytest.raises(SceneError) as e:
        clockwork.simulate(fmu_file("Pendulum"), **kwargs)
    assert f": {named}: expected a step >= master.min_step" in str(e.value), str(e.value)
