"""noSetFMUStatePriorToCurrentPoint: true wherever the master will set no
earlier state, false only while it holds one (Checkpoints.held in Python,
!snap_valid in cw_step.c), on both engines and on FMI 2.0 and 3.0.

The test FMU is tests/models/TestForget: it counts the flags it is given
and, as libcosim's quarter-truck Wheel does, does not keep a step taken
with the flag false (x stays where it was). A master that passes false on
every step (as clockwork did) leaves x at 0.
"""

from __future__ import annotations

import math

import pytest

from clockwork.engine import MasterSettings, System
from cwtest import test_fmu

ENGINES = ("python", "compiled")


def forget(version: int):
    return test_fmu("TestForget") if version == 2 else test_fmu("fmi3/TestForget")


def counts(system, name="forget"):
    x, kept, forgotten = system.instances[name].get_values(["x", "kept", "forgotten"])
    return x, kept, forgotten


@pytest.mark.parametrize("version", (2, 3))
@pytest.mark.parametrize("engine", ENGINES)
def test_no_checkpoint_means_true(engine, version):
    """Without a checkpoint (no event location, no rollback), every step is
    told that no earlier state will be set: the FMU keeps every step."""
    with System({"forget": (str(forget(version)), {"rate": 2.0})}, [],
                MasterSettings(engine=engine, step=0.1)) as s:
        assert s.master.engine == engine
        s.master.run_until(1.0)
        x, kept, forgotten = counts(s)
    assert (kept, forgotten) == (10, 0)
    assert x == pytest.approx(2.0, rel=1e-12)


CLOCK = {"pendulum": ("Pendulum", dict(Q=1000.0, phi_start=math.radians(6))),
         "escapement": ("GrasshopperEscapement", dict(torque=4e-3, phi_r=math.radians(2)))}
LINKS = ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w",
         "escapement.tau -> pendulum.tau_escapement"]


@pytest.mark.parametrize("engine", ENGINES)
def test_beside_a_clock_without_event_location(engine):
    """The clock's FMUs beside it, event location off: no checkpoint, every
    step kept, on both engines alike."""
    comps = dict(CLOCK, forget=(str(forget(2)), {}))
    with System(comps, LINKS, MasterSettings(engine=engine, step=0.01, event_location=False)) as s:
        s.master.run_until(0.5)
        x, kept, forgotten = counts(s)
        assert s.master.stats.states_saved == 0
    assert (kept, forgotten) == (50, 0)
    assert x == pytest.approx(0.5, rel=1e-12)


@pytest.mark.parametrize("prediction", (True, False))
@pytest.mark.parametrize("engine", ENGINES)
def test_checkpoint_held_means_false(engine, prediction):
    """Event location keeps a checkpoint from the first step on (a replay
    may go back to it): every step is told that an earlier state may be set
    again, on both engines, with the same counts; also where the switches
    are landed on by prediction, without a rollback (a miss would replay
    from the checkpoint)."""
    comps = dict(CLOCK, forget=(str(forget(2)), {}))
    with System(comps, LINKS, MasterSettings(engine=engine, step=0.01, event_prediction=prediction)) as s:
        s.master.run_until(2.0)
        x, kept, forgotten = counts(s)
        stats = s.master.stats
    assert stats.events > 0
    if prediction:
        assert stats.predicted_landings > 0
    else:
        assert stats.rollbacks > 0
    assert kept == 0 and forgotten >= stats.steps
    assert x == 0.0


def test_same_counts_on_both_engines():
    comps = dict(CLOCK, forget=(str(forget(2)), {}))
    seen = []
    for engine in ENGINES:
        with System(comps, LINKS, MasterSettings(engine=engine, step=0.01)) as s:
            s.master.run_until(2.0)
            seen.append(counts(s))
    assert seen[0] == seen[1]


@pytest.mark.parametrize("engine", ENGINES)
def test_rollback_settings_mean_false(engine):
    """Strong coupling saves a state at every step and may set it again:
    every step is told so (on the compiled core too, which iterates)."""
    comps = {"forget": (str(forget(2)), {}), "decay": (str(test_fmu("TestDecay")), {})}
    with System(comps, ["forget.x -> decay.v"], MasterSettings(engine=engine, step=0.1, iterations=2)) as s:
        assert s.master.engine == engine
        s.master.run_until(0.5)
        x, kept, forgotten = counts(s)
    assert kept == 0 and forgotten >= 5
