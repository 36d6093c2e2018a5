"""The master's settings are one type (engine/settings.py, MasterSettings):
every field is a key of a scene's [master] table, of --set master.<key>, of
clockwork.simulate(master={...}) and of an SSP's clockwork annotation; each
is checked by the one declaration beside its field, and a refusal names
where the value came from (the scene key, the --set, the argument, the
SSD's attribute) and what its declaration expects.

GOOD and BAD hold a value for every field: a field added to MasterSettings
without them fails here, and the scene's key list is the type's (a field
added to the type alone is a scene key; none can be added to the scene
alone)."""

from __future__ import annotations

import dataclasses
import shutil

import pytest

import clockwork
import clockwork.api
from clockwork.engine.settings import DEFAULTS, SETTINGS, MasterSettings
from clockwork.errors import SceneError
from clockwork.run import load_scene
from clockwork.scene.model import show
from clockwork.scene.save import toml_value
from cwtest import fmu_file

# A value of each field other than its default, that a one-pendulum scene runs with.
GOOD = {
    "step": 0.02, "order": "jacobi", "extrapolation": 1, "event_location": False, "event_prediction": False,
    "event_time_tolerance": 1e-9, "event_indicator_tolerance": 1e-10, "iterations": 2, "iteration_tolerance": 1e-8,
    "richardson": True, "richardson_tolerance": 1e-6, "min_step": 1e-8, "max_step": 0.05, "engine": "python",
    "tolerance": 1e-6, "fmi_version": 3, "early_return": False, "me_solver": "dp54", "algebraic_loops": "delay",
    "threads": 2, "divergence_limit": 1e6, "me_groups": False,
}
# richardson does not iterate the coupling: each of the two is tried alone
ALONE = {"iterations": {"richardson": False}, "richardson": {"iterations": 0}}

# A value of each field out of its kind or range.
BAD = {
    "step": 0, "order": "random", "extrapolation": 3, "event_location": 1, "event_prediction": "yes",
    "event_time_tolerance": -1e-9, "event_indicator_tolerance": 0, "iterations": -1, "iteration_tolerance": 0.0,
    "richardson": 0, "richardson_tolerance": -1.0, "min_step": 0.0, "max_step": -0.5, "engine": "gpu",
    "tolerance": 0, "fmi_version": 1, "early_return": "no", "me_solver": "rk4", "algebraic_loops": "solved",
    "threads": 257, "divergence_limit": -1e8, "me_groups": "no",
}
# More refused values: the bounds and the kinds
MORE_BAD = [("threads", 0), ("iterations", 2**31), ("iterations", 1.5), ("extrapolation", True), ("step", "0.1"),
            ("tolerance", True), ("fmi_version", 2.0), ("order", 1), ("divergence_limit", 10**400)]

SCENE = """\
[scene]
title = "one pendulum"
[components.p]
fmu = "Pendulum"
[experiment]
stop = 0.1
[master]
{master}
"""


def test_every_field_has_a_value_here_and_a_declaration():
    fields = [f.name for f in dataclasses.fields(MasterSettings)]
    assert list(SETTINGS) == fields and list(DEFAULTS) == fields
    assert set(GOOD) == set(fields), "a new field needs a value in GOOD (and BAD): settable from everywhere"
    assert set(BAD) == set(fields)
    assert all(GOOD[k] != DEFAULTS[k] for k in fields)
    assert MasterSettings().as_dict() == DEFAULTS


def test_the_scene_keys_are_the_fields(tmp_path):
    """The [master] table allows exactly MasterSettings' fields (the list
    the refusal of an unknown key gives), and so do --set and an SSP."""
    scene = _scene(tmp_path, {"nope": 1})
    with pytest.raises(SceneError) as e:
        load_scene(scene)
    assert e.value.detail.endswith("allowed: " + ", ".join(sorted(SETTINGS))), str(e.value)


def _scene(tmp_path, master: dict):
    fmu_file("Pendulum")
    scene = tmp_path / "s.toml"
    scene.write_text(SCENE.format(master="\n".join(f"{k} = {toml_value(v)}" for k, v in master.items())))
    return scene


def _simulated_scene(monkeypatch, path, **kw):
    """The scene clockwork.simulate would run (it stops before the run)."""
    seen = []

    def stop(scene, *a, **k):
        seen.append(scene)
        raise _Stop

    monkeypatch.setattr(clockwork.api, "time_series", stop)
    with pytest.raises(_Stop):
        clockwork.simulate(path, **kw)
    return seen[0]


class _Stop(Exception):
    pass


@pytest.mark.parametrize("key", list(GOOD))
def test_every_field_is_settable_from_a_scene_set_and_simulate(tmp_path, monkeypatch, key):
    value, others = GOOD[key], ALONE.get(key, {})
    from_file = load_scene(_scene(tmp_path, {key: value, **others})).master
    from_set = load_scene(_scene(tmp_path, others), [f"master.{key}={toml_value(value)}"]).master
    from_call = _simulated_scene(monkeypatch, _scene(tmp_path, others), master={key: value}).master
    for m in (from_file, from_set, from_call):
        assert isinstance(m, MasterSettings)  # the scene holds the one type
        assert getattr(m, key) == value and type(getattr(m, key)) is type(value), (key, m)
    assert getattr(MasterSettings(**{key: value, **others}), key) == value


def _bad_line(origin: str, key: str, value) -> str:
    return f"{origin} = {show(value)}: expected {SETTINGS[key].expected}"


@pytest.mark.parametrize("key", list(BAD))
def test_every_field_is_refused_out_of_range_naming_where_it_came_from(tmp_path, monkeypatch, key):
    value = BAD[key]
    path = _scene(tmp_path, {key: value})
    with pytest.raises(SceneError) as e:
        load_scene(path)
    assert str(e.value) == f"{path}: " + _bad_line(f"master.{key}", key, value)
    good = _scene(tmp_path, {})
    with pytest.raises(SceneError) as e:
        load_scene(good, [f"master.{key}={toml_value(value)}"])
    assert str(e.value) == f"{good}: " + _bad_line(f"--set master.{key}", key, value)
    with pytest.raises(SceneError) as e:
        _simulated_scene(monkeypatch, good, master={key: value})
    assert str(e.value) == f"{good}: " + _bad_line(f"master['{key}']", key, value)
    with pytest.raises(SceneError) as e:
        MasterSettings(**{key: value})
    assert str(e.value) == f"master.{key} = {value!r}: expected {SETTINGS[key].expected}"


@pytest.mark.parametrize("key, value", MORE_BAD, ids=[f"{k}={v!r}"[:40] for k, v in MORE_BAD])
def test_the_type_refuses_each_kind_and_bound(key, value):
    with pytest.raises(SceneError) as e:
        MasterSettings(**{key: value})
    assert str(e.value).startswith(f"master.{key} = ") and SETTINGS[key].expected in str(e.value)
    s = MasterSettings()
    setattr(s, key, value)  # changed after it was made: the master's check refuses it too
    with pytest.raises(SceneError, match=f"master.{key}"):
        s.check()


def test_numbers_are_held_as_the_fields_kind():
    import numpy as np

    s = MasterSettings(step=np.float32(0.5), iterations=np.int64(3), divergence_limit=10, extrapolation=np.int8(1))
    assert (type(s.step), type(s.iterations), type(s.divergence_limit), type(s.extrapolation)) == (float, int, float,
                                                                                                  int)


def test_max_step_follows_the_step_in_a_scene_only(tmp_path):
    """max_step: None (no cap) in the type; a scene that does not give it
    caps step doubling at its step, and a --set or sweep of the step moves
    the cap with it (the scene path's default before the one type)."""
    assert MasterSettings(step=0.5).max_step is None
    s = load_scene(_scene(tmp_path, {"step": 0.02}))
    assert (s.master.max_step, s.max_step_given) == (0.02, False)
    assert load_scene(_scene(tmp_path, {}), ["master.step=0.04"]).master.max_step == 0.04
    assert s.variant({("master", "step"): 0.03}).master.max_step == 0.03
    given = load_scene(_scene(tmp_path, {"max_step": 0.05}))
    assert (given.master.max_step, given.max_step_given) == (0.05, True)
    assert given.variant({("master", "step"): 0.03}).master.max_step == 0.05


@pytest.mark.parametrize("key", ["step", "threads", "engine", "richardson", "divergence_limit"])
def test_an_ssp_annotation_is_refused_naming_its_attribute(tmp_path, key):
    fmu = fmu_file("Pendulum")
    (tmp_path / "resources").mkdir()
    shutil.copy(fmu, tmp_path / "resources" / "Pendulum.fmu")
    text = toml_value(BAD[key]).strip('"')
    ssd = tmp_path / "s.ssd"
    ssd.write_text(f"""<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" version="1.0" name="s">
  <ssd:System name="root">
    <ssd:Elements>
      <ssd:Component name="p" source="resources/Pendulum.fmu"/>
    </ssd:Elements>
    <ssd:Annotations><ssc:Annotation type="clockwork"><cw:Settings xmlns:cw="urn:clockwork:ssp:1">
      <cw:Master {key}="{text}"/></cw:Settings></ssc:Annotation></ssd:Annotations>
  </ssd:System>
  <ssd:DefaultExperiment startTime="0" stopTime="0.1"/>
</ssd:SystemStructureDescription>
""")
    with pytest.raises(SceneError) as e:
        load_scene(ssd)
    msg = str(e.value)
    assert e.value.path == str(ssd) and key in e.value.key and "cw:Master" in e.value.key, msg
    assert msg.endswith(f": expected {SETTINGS[key].expected}"), msg
