"""Event location and extrapolation across rates (engine/multirate.py,
TimedMultiRate): the master's accurate step with components at their own
steps. The plain multi-rate rule and its refusals: tests/test_multirate.py."""

import numpy as np
import pytest

from cwtest import ROOT, run_cli

from clockwork.analyses.context import build_system
from clockwork.engine import MasterSettings, System
from clockwork.errors import SceneError
from clockwork.run.catalog import load_scene

# The pendulum and the mechanism vibration exchanging phi and the coupling
# torque (neither with direct feedthrough), the vibration slow.
COMPS = {"p": ("Pendulum", {"phi_start": 0.2}), "v": ("MechanismVibration", {"kappa": 0, "C1": 20})}
BOTH_WAYS = ["p.phi -> v.a1", "v.tau -> p.tau_coupling"]


def trajectory(links, step, rates=None, extrapolation=0, stop=1.8, every=0.03):
    """(p.phi, v.a2) at every `every` s up to `stop`."""
    settings = MasterSettings(step=step, extrapolation=extrapolation, engine="python")
    out = []
    with System(COMPS, links, settings, record={"p": ["phi"], "v": ["a2"]},
                **({"rates": rates} if rates else {})) as s:
        for n in range(1, round(stop / every) + 1):
            s.master.run_until(n * every)
            out.append((s.output("p", "phi"), s.output("v", "a2")))
    return np.array(out)


@pytest.mark.parametrize("links, column", [(["p.phi -> v.a1"], 1), (BOTH_WAYS, 0), (BOTH_WAYS, 1)])
def test_extrapolation_across_rates_follows_the_fine_run_closer_than_a_hold(links, column):
    """The slow vibration (every 3 base steps) gets the pendulum's angle as
    a polynomial over its own step, and the pendulum gets the vibration's
    torque as the polynomial through its points: both orders come closer
    to the single-rate run at a fine step than the zero-order hold does,
    the second closer than the first."""
    fine = trajectory(links, 0.001)[:, column]
    errors = [np.max(np.abs(trajectory(links, 0.01, {"v": 3}, order)[:, column] - fine)) for order in (0, 1, 2)]
    assert errors[1] < 0.5 * errors[0] and errors[2] < errors[1], errors


def test_extrapolation_across_rates_is_the_python_engines_with_its_reason():
    with System(COMPS, BOTH_WAYS, MasterSettings(step=0.01, extrapolation=2), rates={"v": 3}) as s:
        assert s.master.engine == "python"
        assert s.master.engine_reason == ("the compiled core holds inputs over a step across rates (v every 3 base "
                                          "steps): master.extrapolation = 2")


def test_restart_runs_the_same_numbers_again_with_polynomials():
    with System(COMPS, BOTH_WAYS, MasterSettings(step=0.01, extrapolation=2), rates={"v": 3},
                record={"p": ["phi"], "v": ["a2"]}) as s:
        s.master.run_until(0.31)
        first = (s.output("p", "phi"), s.output("v", "a2"))
        s.restart({n: dict(params) for n, (_, params) in COMPS.items()})
        s.master.run_until(0.31)
        assert (s.output("p", "phi"), s.output("v", "a2")) == first


CLOCK = (ROOT / "scenarios" / "core_vibration.toml").read_text()


def clock_scene(tmp_path, name, vibration_step=None, base="0.01 s", stop="6 s", one_way=False):
    text = CLOCK.replace('stop = "202 s"', f'stop = "{stop}"').replace(
        'step = "0.01 s"', f'step = "{base}"\nengine = "python"')  # the same loop both ways
    if vibration_step:
        text = text.replace("[components.vibration]\n", f'[components.vibration]\nstep = "{vibration_step}"\n')
    if one_way:
        text = text.replace('  "vibration.tau -> pendulum.tau_coupling",\n', "")
    f = tmp_path / f"{name}.toml"
    f.write_text(text)
    return load_scene(f)


def events(scene, stop):
    """The located event times up to `stop`, and for each, the time each
    component's outputs were read at (all of them land on it)."""
    found = []
    with build_system(scene) as s:
        m = s.master

        def at(master):
            if master.after_event_step:
                found.append((master.t, {p.inst.name: p.out_time for p in master.ports.all}))

        m.run_until(stop, on_point=at)
        return found, m.stats


def test_a_slow_component_lands_on_every_event_the_fast_ones_locate(tmp_path):
    """The clock with the vibration every 3 base steps, fed by the pendulum
    only: the pendulum and the escapement locate the same events, at the
    same times to the bit, as with the vibration at every base step, and
    the vibration lands on each (its outputs read there)."""
    slow, stats = events(clock_scene(tmp_path, "slow", "0.03 s", one_way=True), 6.0)
    every, _ = events(clock_scene(tmp_path, "every", one_way=True), 6.0)
    assert len(slow) > 4 and stats.events == len(slow)
    assert [t for t, _ in slow] == [t for t, _ in every]
    for t, read in slow:
        assert read == {"pendulum": t, "escapement": t, "vibration": t}


def test_located_events_across_rates_are_as_close_to_a_fine_run_as_the_slow_step_allows(tmp_path):
    """Both ways coupled, the vibration every 2 base steps (0.02 s, the
    pendulum and the escapement at 0.01 s): each located event is as close
    to the single-rate run at a fine step (0.0025 s) as the single-rate run
    with every component at 0.02 s comes, or closer (the vibration's
    torque reaches the pendulum at 0.02 s either way; the difference is
    the coupling's, not the location's, which the one-way test shows to
    be bit for bit)."""
    slow, _ = events(clock_scene(tmp_path, "slow", "0.02 s"), 6.0)
    fine, _ = events(clock_scene(tmp_path, "fine", base="0.0025 s"), 6.0)
    coarse, _ = events(clock_scene(tmp_path, "coarse", base="0.02 s"), 6.0)
    assert len(slow) == len(fine) == len(coarse) > 4
    fine = np.array([t for t, _ in fine])
    gap = np.max(np.abs(np.array([t for t, _ in slow]) - fine))
    assert 0 < gap <= np.max(np.abs(np.array([t for t, _ in coarse]) - fine)), gap


def test_event_location_runs_across_rates_and_is_the_python_engines(tmp_path, capsys):
    f = tmp_path / "clock.toml"
    f.write_text(CLOCK.replace('stop = "202 s"', 'stop = "1 s"').replace(
        "[components.vibration]\n", '[components.vibration]\nstep = "0.03 s"\n'))
    rc, _, err = run_cli(capsys, ["run", f, "--out", tmp_path / "o", "--no-progress"])
    assert rc == 0, err
    summary = (tmp_path / "o" / "summary.json").read_text()
    assert "the compiled core holds inputs over a step across rates (vibration every 3 base steps): " \
           "master.extrapolation = 2" in summary


def test_indicators_fed_by_a_slow_component_are_one_line_in_system_too():
    """(The scene's line: tests/test_multirate.py.) An escapement at the
    base step reading a slow pendulum's angle would see it change at the
    pendulum's points only."""
    comps = {"pendulum": ("Pendulum", {}), "escapement": ("GrasshopperEscapement", {})}
    with pytest.raises(SceneError, match="escapement's event indicators read pendulum's outputs"):
        System(comps, ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w",
                       "escapement.tau -> pendulum.tau_escapement"], MasterSettings(step=0.01),
               rates={"pendulum": 2})
