"""Reused FMU instances: a sweep's points in one process share them.

``System.restart`` (fmi2Reset, new parameters, initialization again) must
give the same bits as a new System, and a sweep run with reuse the same
results as each point run alone, on both engines. A point that failed
leaves nothing behind for the next.
"""

from __future__ import annotations

import math

import pytest

from clockwork.analyses.context import build_system, reusing_systems
from clockwork.engine import MasterSettings, System
from clockwork.errors import ParametersRefused, SimulationError
from clockwork.run.catalog import load_scene
from clockwork.run.points import run_point
from cwtest import CLOCK_SCENE

CLOCK = {"pendulum": ("Pendulum", dict(Q=1000.0, phi_start=math.radians(6))),
         "escapement": ("GrasshopperEscapement", dict(torque=4e-3, phi_r=math.radians(2)))}
LINKS = ["pendulum.phi -> escapement.phi", "pendulum.w -> escapement.w",
         "escapement.tau -> pendulum.tau_escapement"]


def _trace(system, stop=3.0):
    m = system.master
    rows = []
    while m.t < stop - 1e-9:
        m.step(min(m.settings.step, stop - m.t))
        rows.append((m.t, list(m.ports.buffer)))
    return rows, vars(m.stats).copy()


@pytest.mark.parametrize("engine", ["python", "compiled"])
@pytest.mark.parametrize("settings", [dict(step=0.05), dict(step=0.02, extrapolation=2, order="jacobi")])
def test_a_restarted_system_is_a_new_system(engine, settings):
    other = {"pendulum": dict(Q=300.0, phi_start=math.radians(11), L=0.7),
             "escapement": dict(torque=7e-3, phi_r=math.radians(3))}
    ms = MasterSettings(engine=engine, **settings)
    with System(CLOCK, LINKS, ms) as fresh:
        expected = _trace(fresh)
    with System({n: (m, other[n]) for n, (m, _) in CLOCK.items()}, LINKS, ms) as reused:
        _trace(reused, 5.0)  # another clock first, run past events and rollbacks
        reused.master.on_step = lambda m: None
        reused.restart({n: p for n, (_, p) in CLOCK.items()})
        assert reused.master.on_step is None
        assert _trace(reused) == expected


def _without_wall_times(result: dict) -> dict:
    return {k: v for k, v in result.items() if k != "wall_time_s"}


SWEEP = ('[sweep]\naxes = [{ parameter = "escapement.torque", values = ["0.3 N.cm", "0.5 N.cm", "0.4 N.cm"] },'
         ' { parameter = "pendulum.Q", values = [800, 1200] }]')


@pytest.mark.parametrize("engine", ["python", "compiled"])
@pytest.mark.parametrize("scene_of", [
    lambda tmp: (tmp / "clock.toml", CLOCK_SCENE.format(stop=2, sweep=SWEEP)),
    lambda tmp: ("ziemkiewicz_fig4a", None),
], ids=["time_series", "steady_state"])
def test_a_sweep_with_reuse_gives_what_each_point_gives_alone(tmp_path, engine, scene_of):
    path, text = scene_of(tmp_path)
    if text is not None:
        path.write_text(text)
    scene = load_scene(path, [f"master.engine={engine}"])
    points = scene.points()[:8]
    with reusing_systems():
        shared = [run_point(scene, p) for p in points]
    alone = [run_point(scene, p) for p in points]
    assert len(points) >= 6
    assert [_without_wall_times(r) for r in shared] == [_without_wall_times(r) for r in alone]


def test_the_instances_are_really_reused(tmp_path):
    path = tmp_path / "clock.toml"
    path.write_text(CLOCK_SCENE.format(stop=0.2, sweep=SWEEP))
    scene = load_scene(path)
    points = scene.points()
    components = set()
    with reusing_systems():
        for p in points:
            with build_system(scene, p) as s:
                components.add(tuple(i.component for i in s.instances.values()))
                assert s.parameters["escapement"]["torque"] == p[("escapement", "torque")]
    assert len(components) == 1
    with build_system(scene, points[0]) as s:  # outside: a new system, freed at the end
        instances = list(s.instances.values())
    assert all(i._slave is None for i in instances)


def test_a_failed_point_does_not_hand_on_its_instances(tmp_path):
    path = tmp_path / "clock.toml"
    path.write_text(CLOCK_SCENE.format(stop=0.2, sweep=SWEEP))
    scene = load_scene(path)
    p0, p1 = scene.points()[:2]
    with reusing_systems():
        with pytest.raises(SimulationError):
            with build_system(scene, p0) as s:
                failed = list(s.instances.values())
                raise SimulationError("a point that failed")
        assert all(i._slave is None for i in failed)  # freed, not kept
        with build_system(scene, p1) as s:
            assert all(i not in failed for i in s.instances.values())


def test_refused_parameters_at_a_restart_are_reported_as_at_a_new_build(tmp_path):
    path = tmp_path / "clock.toml"
    path.write_text(CLOCK_SCENE.format(stop=0.2, sweep=SWEEP))
    scene = load_scene(path)
    good = scene.points()[0]
    bad = {**good, ("pendulum", "L"): -1.0}
    with pytest.raises(ParametersRefused) as fresh:
        build_system(scene, bad)
    with reusing_systems():
        with build_system(scene, good):
            pass
        with pytest.raises(ParametersRefused) as reused:
            build_system(scene, bad)
        with build_system(scene, good) as s:  # and the next point still runs
            s.master.run_until(0.1)
    assert str(reused.value) == str(fresh.value)
