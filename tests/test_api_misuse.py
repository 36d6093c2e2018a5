"""The Python API fails as clearly as the command line.

Every misuse of System, its master and MasterSettings raises a subclass of
clockwork.errors.ClockworkError naming what was wrong: closed objects,
times, settings, names and types. None crashes the interpreter or hangs;
the closed-object cases run in a child process, so that a crash is a
failed test, not a dead test run.
"""

from __future__ import annotations

import math
import subprocess
import sys
import textwrap

import pytest

from clockwork.engine import MasterSettings, System
from clockwork.errors import ClockworkError, ClosedError, SceneError, UsageError

from cwtest import FMU_DIR, ROOT, fmu_file, test_fmu

ENGINES = ["python", "compiled", "auto"]
COMPONENTS = {"pendulum": ("Pendulum", {"Q": 1000.0, "phi_start": 0.1}),
              "escapement": ("GrasshopperEscapement", {"torque": 0.004})}
LINKS = ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w",
         "escapement.tau -> pendulum.tau_escapement"]


@pytest.fixture(autouse=True)
def _fmus(monkeypatch):
    fmu_file("Pendulum")
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))


def _system(engine, **kw):
    return System(kw.pop("components", COMPONENTS), kw.pop("links", LINKS),
                  MasterSettings(step=0.5, engine=engine), **kw)


# --- closed objects -------------------------------------------------------------

USES_AFTER_CLOSE = {
    "run_until": "s.master.run_until(10.0)",
    "run_until via a kept master": "m.run_until(10.0)",
    "step via a kept master": "m.step()",
    "value": "s.value('pendulum', 'phi')",
    "output": "s.output('pendulum', 'phi')",
    "restart": "s.restart({'pendulum': {'Q': 500.0}, 'escapement': {}})",
}

_CLOSED = textwrap.dedent("""
    import sys
    from clockwork.engine import MasterSettings, System
    from clockwork.errors import ClosedError
    links = {links!r}
    with System({components!r}, links, MasterSettings(step=0.5, engine={engine!r})) as s:
        m = s.master
        m.run_until(1.0)
    {free}
    try:
        {use}
    except ClosedError as e:
        print("ClosedError:", e)
        sys.exit(0)
    print("no error")
    sys.exit(3)
""")


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("use", list(USES_AFTER_CLOSE))
@pytest.mark.parametrize("how", ["with", "free"])
def test_a_closed_system_raises_not_crashes(engine, use, how):
    code = _CLOSED.format(links=LINKS, components=COMPONENTS, engine=engine,
                          free="s.free(); s.free()" if how == "free" else "", use=USES_AFTER_CLOSE[use])
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60,
                       env={"CLOCKWORK_FMU_DIR": str(FMU_DIR), "PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"})
    assert r.returncode == 0, (r.returncode, r.stdout, r.stderr[-500:])
    assert "freed" in r.stdout


# --- times ----------------------------------------------------------------------

@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("t", [math.nan, math.inf, -math.inf, 0.5, -1.0, "10", None, True])
def test_run_until_refuses_a_time_that_is_not_ahead(engine, t):
    with _system(engine) as s:
        s.master.run_until(1.0)
        with pytest.raises(UsageError, match="run_until"):
            s.master.run_until(t)
        assert s.master.t == 1.0  # nothing happened
        s.master.run_until(1.0)  # the present is allowed: nothing to do


# --- settings -------------------------------------------------------------------

BAD_SETTINGS = [
    {"step": 0}, {"step": -0.1}, {"step": math.nan}, {"step": math.inf}, {"step": "0.1"},
    {"min_step": 0.0}, {"max_step": -1.0}, {"max_step": math.inf},
    {"event_time_tolerance": math.nan}, {"iteration_tolerance": -1e-9}, {"richardson_tolerance": 0},
    {"divergence_limit": math.inf}, {"event_indicator_tolerance": None},
    {"iterations": -1}, {"iterations": 1.5}, {"extrapolation": 3}, {"extrapolation": True},
    {"event_location": "yes"}, {"event_prediction": 1}, {"richardson": 1},
    {"order": "random"}, {"engine": "gpu"},
]


@pytest.mark.parametrize("bad", BAD_SETTINGS, ids=[repr(b) for b in BAD_SETTINGS])
def test_invalid_settings_are_refused_at_construction(bad):
    with pytest.raises(SceneError) as e:
        MasterSettings(**bad)
    assert f"master.{next(iter(bad))}" in str(e.value)


# --- names and types ----------------------------------------------------------------

BAD_SYSTEMS = {
    "link from a missing variable": ({"links": ["pendulum.phx -> escapement.phi"] + LINKS[1:]}, ["pendulum", "phx"]),
    "link to a missing variable": ({"links": LINKS[:2] + ["escapement.tau -> pendulum.nope"]}, ["pendulum", "nope"]),
    "link from an unknown instance": ({"links": ["pendulm.phi -> escapement.phi"] + LINKS[1:]}, ["pendulm", "phi"]),
    "link into an output": ({"links": LINKS + ["pendulum.phi -> escapement.tau"]}, ["escapement", "tau"]),
    "unknown parameter": ({"components": {**COMPONENTS, "pendulum": ("Pendulum", {"Qq": 1.0})}}, ["pendulum", "Qq"]),
    "recorded output unknown": ({"record": {"pendulum": ["tick"]}}, ["pendulum", "tick"]),
    "recorded instance unknown": ({"record": {"clock": ["tick_time"]}}, ["clock", "tick_time"]),
    "components not a dict": ({"components": [("Pendulum", {})]}, ["components"]),
    "component not a pair": ({"components": {"pendulum": "Pendulum"}}, ["components"]),
}


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("case", list(BAD_SYSTEMS))
def test_bad_names_and_types_raise_the_projects_error(engine, case):
    kw, needles = BAD_SYSTEMS[case]
    with pytest.raises(ClockworkError) as e:
        _system(engine, **dict(kw))
    for n in needles:
        assert n in str(e.value), (n, str(e.value))


@pytest.mark.parametrize("engine", ENGINES)
def test_lookups_on_a_live_system_name_instance_and_variable(engine):
    with _system(engine) as s:
        for call in (lambda: s.value("pendulum", "phx"), lambda: s.value("nobody", "phi"),
                     lambda: s.output("pendulum", "nope"),
                     lambda: s.restart({"pendulum": {"Qx": 1.0}})):
            with pytest.raises(UsageError) as e:
                call()
            assert "." in str(e.value)


def test_every_error_is_a_clockwork_error():
    assert issubclass(ClosedError, UsageError) and issubclass(UsageError, ClockworkError)
    assert issubclass(SceneError, ClockworkError)


def test_numpy_numbers_are_numbers():
    import numpy as np

    s = MasterSettings(step=np.float64(0.5), iterations=np.int64(0), min_step=np.float32(1e-9))
    assert s.step == 0.5
    with _system("auto") as sys_:
        sys_.master.run_until(np.int64(1))
        assert sys_.master.t == 1.0


# --- every public entry point, every argument, every other kind of value ---------------
#
# The entry points declare their arguments (clockwork.arguments.checked, and
# the master's in engine.system.MASTER_ARGUMENTS); each argument is given, in
# turn, every sample value its spec refuses, the others good: one UsageError
# naming the call and the argument, and nothing happened.

from clockwork.arguments import public_calls  # noqa: E402
from clockwork.engine.marks import Marks  # noqa: E402
from clockwork.engine.system import MASTER_ARGUMENTS, STEP_PARTS  # noqa: E402

GOOD_SYSTEM = {"components": COMPONENTS, "connections": LINKS, "settings": MasterSettings(step=0.5),
               "record": {"pendulum": ["tick_time"]}, "start_time": 0.0, "model_descriptions": None}
GOOD_CALLS = {
    "System.restart": {"parameters": {"pendulum": {"Q": 1000.0, "phi_start": 0.1}}},
    "System.value": {"instance": "pendulum", "name": "phi"},
    "System.output": {"instance": "pendulum", "name": "phi"},
    "step": {"h": 0.5},
    "run_until": {"t_stop": 1.0, "on_point": None},
    "run_marks": {"t_stop": 1.0, "marks": Marks([0.5]), "on_rows": None},
    "initialize": {"parameters": {"pendulum": {"Q": 1000.0}}},
    "reinitialize": {"parameters": {"pendulum": {"Q": 1000.0}}},
    "restart": {"parameters": {"pendulum": {"Q": 1000.0}}},
}
SYSTEM_CALLS = public_calls(System)


def _cases(calls: dict) -> list:
    return [pytest.param(call, arg, bad, id=f"{call}-{arg}-{type(bad).__name__}:{str(bad)[:12]}")
            for call, specs in calls.items() for arg, spec in specs.items() for bad in spec.refused()]


def test_every_public_method_declares_its_arguments():
    """A public method of System or of either master that takes arguments
    and declares none would let any value through: the class is covered,
    not the examples."""
    import inspect

    from clockwork.engine.compiled import CompiledMaster
    from clockwork.engine.master import Master

    for name, f in vars(System).items():
        if not name.startswith("_") and callable(f) and len(inspect.signature(f).parameters) > 1:
            assert hasattr(f, "__arguments__"), f"System.{name}"
    assert hasattr(System.__init__, "__arguments__")
    for cls in (Master, CompiledMaster):
        for name in dir(cls):
            f = getattr(cls, name)
            if name.startswith("_") or name in STEP_PARTS or not callable(f) or isinstance(f, type):
                continue
            numbers_or_maps = [p for p in list(inspect.signature(f).parameters)[1:]]
            if numbers_or_maps:
                assert name in MASTER_ARGUMENTS, f"{cls.__name__}.{name}"
    assert set(GOOD_CALLS) >= {c for c in SYSTEM_CALLS if c != "System.__init__"} | set(MASTER_ARGUMENTS)


@pytest.mark.parametrize("call, arg, bad", _cases({"System.__init__": System.__init__.__arguments__}))
def test_system_refuses_every_other_kind_of_argument(call, arg, bad):
    kwargs = dict(GOOD_SYSTEM, **{arg: bad})
    with pytest.raises(UsageError) as e:
        System(**kwargs)
    assert f"System(): {arg}" in str(e.value), str(e.value)


@pytest.fixture(scope="module", params=["python", "compiled"])
def live(request):
    import os

    fmu_file("Pendulum")
    before = os.environ.get("CLOCKWORK_FMU_DIR")
    os.environ["CLOCKWORK_FMU_DIR"] = str(FMU_DIR)
    try:
        with System(COMPONENTS, LINKS, MasterSettings(step=0.5, engine=request.param),
                    record={"pendulum": ["tick_time"]}) as s:
            yield s
    finally:
        if before is None:
            os.environ.pop("CLOCKWORK_FMU_DIR", None)
        else:
            os.environ["CLOCKWORK_FMU_DIR"] = before


@pytest.mark.parametrize("call, arg, bad", _cases({c: f.__arguments__ for c, f in SYSTEM_CALLS.items()
                                                   if c != "System.__init__"}
                                                  | MASTER_ARGUMENTS))
def test_methods_refuse_every_other_kind_of_argument(live, call, arg, bad):
    t, steps = live.master.t, live.master.stats.steps
    if call.startswith("System."):
        method = getattr(live, call.split(".")[1])
    else:
        method = getattr(live.master, call)
    kwargs = dict(GOOD_CALLS[call], **{arg: bad})
    with pytest.raises(UsageError) as e:
        method(**kwargs)
    assert f"{arg} = " in str(e.value) or f"{arg}[" in str(e.value), str(e.value)
    assert live.master.t == t and live.master.stats.steps == steps  # nothing happened


@pytest.mark.parametrize("engine", ["python", "compiled"])
def test_a_call_of_the_wrong_shape_is_a_usage_error(engine):
    with _system(engine) as s:
        for call in (lambda: s.value("pendulum"), lambda: s.value("pendulum", "phi", "x"),
                     lambda: s.value(instance="pendulum", nam="phi"),
                     lambda: s.value("pendulum", instance="pendulum"),
                     lambda: s.master.step(), lambda: s.master.step(0.1, 0.2), lambda: s.master.run_until(),
                     lambda: s.restart()):
            with pytest.raises(UsageError):
                call()
    for call in (lambda: System(), lambda: System(COMPONENTS), lambda: System(COMPONENTS, LINKS, settingz=1)):
        with pytest.raises(UsageError):
            call()


# --- values of the type their variable declares ------------------------------------------

def _types_fmu():
    from cwtest import test_fmu

    return str(test_fmu("TestTypes"))


WRONG_VALUES = {
    # (a NaN is a Real's value: the FMU takes or refuses it, and a run that turns NaN fails as a simulation)
    "p_real": ["abc", "1.5", [1.0], None, True, {"x": 1}],
    "p_int": [1.5, "2", True, None, 2**40, [1]],
    "p_bool": [1, 0, "true", None, 1.0],
    "p_enum": [1.5, "2", True, None],
    "p_str": [1, None, b"tick", ["tick"]],
}


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("name, bad", [(n, v) for n, vs in WRONG_VALUES.items() for v in vs],
                         ids=[f"{n}={v!r}" for n, vs in WRONG_VALUES.items() for v in vs])
def test_a_parameter_of_the_wrong_type_names_instance_and_variable(engine, name, bad):
    with pytest.raises(UsageError) as e:
        System({"types": (_types_fmu(), {name: bad})}, [], MasterSettings(step=0.1, engine=engine))
    assert f"types.{name}" in str(e.value), str(e.value)
    with System({"types": (_types_fmu(), {})}, [], MasterSettings(step=0.1, engine=engine)) as s:
        with pytest.raises(UsageError) as e:
            s.restart({"types": {name: bad}})
        assert f"types.{name}" in str(e.value)
        s.master.run_until(0.2)  # the refused restart changed nothing


def test_fmi3_parameters_of_every_type_are_checked(tmp_path):
    fmu = str(test_fmu("fmi3/AllTypes"))
    bad = {"Float32": "x", "Float64": [1.0], "Int8": 200, "UInt8": -1, "Int16": 1.5, "UInt16": 2**16,
           "Int32": 2**31, "UInt32": -1, "Int64": 2**63, "UInt64": -1, "Boolean": 1, "String": 3,
           "Binary": "xyz", "Enumeration": 1.0}
    for kind, value in bad.items():
        with pytest.raises(UsageError) as e:
            System({"all": (fmu, {f"p_{kind}": value})}, [], MasterSettings(step=0.1, engine="python"))
        assert f"all.p_{kind}" in str(e.value), str(e.value)
    good = {"Float32": 1.5, "Int8": -100, "UInt64": 2**64 - 1, "Boolean": True, "String": "s", "Binary": "0aff"}
    with System({"all": (fmu, {f"p_{k}": v for k, v in good.items()})}, [], MasterSettings(step=0.1)) as s:
        s.master.run_until(0.1)


# --- pickling and copying -----------------------------------------------------------------

@pytest.mark.parametrize("engine", ["python", "compiled"])
def test_a_system_says_it_cannot_be_pickled_or_copied(engine):
    import copy
    import pickle

    with _system(engine) as s:
        for obj in (s, s.master, s.instances["pendulum"]):
            for how in (pickle.dumps, copy.copy, copy.deepcopy):
                with pytest.raises(ClockworkError) as e:
                    how(obj)
                assert "cannot be pickled" in str(e.value)
        s.master.run_until(1.0)  # still usable


# --- one System, two threads ---------------------------------------------------------------

@pytest.mark.parametrize("engine", ["python", "compiled"])
def test_a_second_thread_is_refused_not_interleaved(engine):
    """Two threads drive one System: the second is refused with a
    UsageError while the first is inside a call; neither sees an FMU error,
    a negative step or a communication point that does not match; the
    system stays consistent and a lone thread can go on with it."""
    import threading

    errors: list[BaseException] = []
    ready = threading.Barrier(2)
    with System(COMPONENTS, LINKS, MasterSettings(step=0.01, engine=engine)) as s:
        def drive():
            ready.wait()
            for _ in range(300):
                try:
                    s.master.run_until(s.master.t + 0.5)
                    s.value("pendulum", "phi")
                except UsageError as e:
                    errors.append(e)
                except BaseException as e:  # noqa: BLE001 (any other error fails the test)
                    errors.append(e)
                    return

        threads = [threading.Thread(target=drive) for _ in range(2)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(120)
        others = [e for e in errors if not isinstance(e, UsageError)]
        assert not others, others
        assert any("another thread" in str(e) for e in errors)
        assert s.master.stats.steps > 0
        t0 = s.master.t
        s.master.run_until(t0 + 1.0)
        assert s.master.t == t0 + 1.0


def test_a_system_can_be_handed_to_another_thread():
    """Refused is only use at the same time: a System built in one thread
    and used in another after it is done is fine."""
    import threading

    with _system("auto") as s:
        s.master.run_until(1.0)
        result = []
        t = threading.Thread(target=lambda: (s.master.run_until(2.0), result.append(s.master.t)))
        t.start()
        t.join(60)
        assert result == [2.0]


# --- clockwork.simulate: every argument, every other kind of value (issue 37) ------------------------------

def _simulate_cases() -> list:
    import clockwork

    return _cases({"simulate": clockwork.simulate.__arguments__})


@pytest.mark.parametrize("call, arg, bad", _simulate_cases())
def test_simulate_refuses_every_other_kind_of_argument(call, arg, bad):
    """Each declared argument of clockwork.simulate given each sample value
    its spec refuses (10**400, complex, Decimal, sets and bytes among them):
    one UsageError naming the argument, before anything is loaded."""
    import clockwork
    from cwtest import test_fmu

    args = {"filename": test_fmu("TestDecay")}
    args[arg] = bad
    with pytest.raises(UsageError) as e:
        clockwork.simulate(**args)
    assert f"simulate(): {arg}" in str(e.value) and "\n" not in str(e.value), str(e.value)


def test_simulate_declares_every_argument():
    import inspect

    import clockwork

    named = [p.name for p in inspect.signature(clockwork.simulate).parameters.values() if p.kind != p.VAR_KEYWORD]
    assert set(clockwork.simulate.__arguments__) == set(named)


@pytest.mark.parametrize("bad", [10**400, -10**400, 2**63])
def test_an_integer_too_large_for_c_is_refused_by_integer_arguments(bad):
    from clockwork.arguments import Integer, Real

    assert not Integer().accepts(bad)
    assert not Real().accepts(10**400)
