"""The engine's one driver, Master.run_marks, and its plan (engine/marks.py):
a plan that cannot be run is refused in one line before anything runs; the
engines' agreement on it is in tests/test_compiled.py, the analyses' use in
tests/figures/test_hoyng.py."""

from __future__ import annotations

import math

import pytest

from clockwork.engine import MasterSettings, System
from clockwork.engine.marks import Marks
from clockwork.errors import UsageError
from cwtest import FMU_DIR, fmu_file


@pytest.mark.parametrize("kwargs, needle", [
    (dict(times=[1.0, 0.5]), "increasing order"),
    (dict(times=[math.nan]), "finite times"),
    (dict(times=[math.inf]), "finite times"),
    (dict(times="ab"), "a list of times"),
    (dict(times=[1.0], sets=[True]), "one of each per mark"),
    (dict(times=[1.0], sets=[True, False], values=[0.0, 1.0]), "one of each per mark"),
    (dict(times=[1.0], sets=[True], values=["x"]), "a list of numbers"),
    (dict(margin=0.0), "margin = 0.0"),
    (dict(margin=math.nan), "margin = nan"),
    (dict(margin=True), "margin = True"),
    (dict(max_step=-1.0), "max_step = -1.0"),
    (dict(tolerance=-1e-9), "tolerance = -1e-09"),
    (dict(watched=[1.0]), "Marks(watched)"),
    (dict(watched=[(None, 0.5)]), "Marks(watched)"),
    (dict(outputs=[(None, 0, 1)]), "Marks(outputs)"),
    (dict(inputs=5), "Marks(inputs)"),
    (dict(watched=[(None, 0)], follow=(0, 1.0)), "needs a margin"),
    (dict(times=[1.0, 2.0], watched=[(None, 0)], follow=(0, 1.0), margin=0.1), "at most one mark"),
    (dict(times=[1.0], sets=[True], values=[1.0], watched=[(None, 0)], follow=(0, 1.0), margin=0.1),
     "which sets nothing"),
    (dict(watched=[(None, 0)], follow=(1, 1.0), margin=0.1), "not one of the 1 watched"),
    (dict(watched=[(None, 0)], follow=(0, 0.0), margin=0.1), "follow period = 0.0"),
    (dict(watched=[(None, 0)], follow=0, margin=0.1), "Marks(follow)"),
])
def test_a_plan_that_cannot_run_is_refused_in_one_line(kwargs, needle):
    with pytest.raises(UsageError) as e:
        Marks(**kwargs)
    assert needle in str(e.value) and "\n" not in str(e.value), str(e.value)


@pytest.fixture(params=["python", "compiled"])
def pair(request, monkeypatch):
    fmu_file("Pendulum")
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))
    systems = [System({"pendulum": ("Pendulum", {"Q": 1000.0, "phi_start": 0.1})}, [],
                      MasterSettings(step=0.1, engine=request.param)) for _ in range(2)]
    with systems[0], systems[1]:
        yield systems


def test_a_plan_of_another_system_is_refused(pair):
    a, b = pair
    port = b.master.ports["pendulum"]
    for kwargs in (dict(watched=[(port, 0)]), dict(outputs=[(port, 0)]), dict(before=[(port, 0)]),
                   dict(inputs=[(b.instances["pendulum"], 0)])):
        with pytest.raises(UsageError, match="this master's"):
            a.master.run_marks(1.0, Marks([0.5], **kwargs))
    mine = a.master.ports["pendulum"]
    with pytest.raises(UsageError, match="not an output position"):
        a.master.run_marks(1.0, Marks([0.5], outputs=[(mine, mine.n_out)]))
    pendulum = a.instances["pendulum"]
    for name in ("phi", "Q"):  # an output, a parameter
        with pytest.raises(UsageError, match="expected the value reference of a Real input of pendulum"):
            a.master.run_marks(1.0, Marks([0.5], inputs=[(pendulum, pendulum.variables[name].vr)]))
    assert a.master.t == 0.0 and a.master.stats.steps == 0


def test_the_stop_time_and_the_plan_are_checked(pair):
    m = pair[0].master
    with pytest.raises(UsageError, match=r"run_marks\(\): marks = .*expected a Marks plan"):
        m.run_marks(1.0, [0.5])
    m.run_marks(0.5, Marks([0.2]))
    with pytest.raises(UsageError, match=r"run_marks\(0.25\): the system is already at t = 0.5"):
        m.run_marks(0.25, Marks())
    assert m.t == 0.5


def test_marks_land_points_and_a_run_goes_on_where_it_stopped(pair):
    """Points on the marks and max_step between them; the plan keeps its
    place across calls; margin steps once no mark lies ahead."""
    m = pair[0].master
    seen = []
    m.on_step = lambda master: seen.append(master.t)
    marks = Marks([0.05, 0.25], margin=0.04, max_step=0.1)
    m.run_marks(0.2, marks)
    assert seen == pytest.approx([0.05, 0.15, 0.2], abs=1e-15) and marks.next == 1
    m.run_marks(0.4, marks)
    assert seen[3:] == pytest.approx([0.25, 0.29, 0.33, 0.37, 0.4], abs=1e-15) and marks.next == 2


def test_a_mark_sets_unconnected_inputs_only(monkeypatch):
    fmu_file("Pendulum")
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))
    with System({"pendulum": ("Pendulum", {"Q": 1000.0, "phi_start": 0.1}), "drag": ("Drag", {})},
                ["pendulum.w -> drag.w", "drag.tau -> pendulum.tau_drag"], MasterSettings(step=0.1)) as s:
        pendulum = s.instances["pendulum"]
        with pytest.raises(UsageError, match="pendulum.tau_drag, which is connected"):
            s.master.run_marks(1.0, Marks([0.5], sets=[True], values=[1.0],
                                          inputs=[(pendulum, pendulum.variables["tau_drag"].vr)]))
        s.master.run_marks(1.0, Marks([0.5], sets=[True], values=[1e-3],
                                      inputs=[(pendulum, pendulum.variables["tau_escapement"].vr)]))
        assert s.master.t == pytest.approx(1.0, abs=1e-12)
