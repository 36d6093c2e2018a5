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

from cwtest import FMU_DIR, ROOT, fmu_file

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
