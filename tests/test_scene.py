"""Scene loading, units and strict validation (clockwork/scene.py, clockwork/units.py).

Bad scenes live in tests/data/scenes/bad_*.toml, one problem each; every
error must name the file, the dotted key and what was expected.
"""

import hashlib
import math
from pathlib import Path

import fmpy
import pytest

from cwtest import FMU_DIR, fmu_file
from clockwork.errors import SceneError
from clockwork.analyses.registry import ANALYSIS_KEYS, _ANALYSIS_CONVERT, register_analysis
from clockwork.run import load_scene
from clockwork.scene import Invalid, parse_override
from clockwork.scene.units import UnitError, fmt, to_seconds, to_unit, unit_conversions

DATA = Path(__file__).resolve().parent / "data" / "scenes"


@pytest.fixture(autouse=True)
def _fmu_dir(monkeypatch):
    fmu_file("Pendulum")  # fails with a build hint when missing
    monkeypatch.setenv("CLOCKWORK_FMU_DIR", str(FMU_DIR))


def error_of(path, overrides=()) -> SceneError:
    with pytest.raises(SceneError) as info:
        load_scene(path, overrides)
    msg = str(info.value)
    assert "\n" not in msg
    return info.value


# --- units --------------------------------------------------------------------

@pytest.fixture(scope="module")
def pendulum_md():
    return fmpy.read_model_description(str(fmu_file("Pendulum")), validate=False)


def test_unit_conversion_uses_display_and_same_base_units(pendulum_md):
    md = pendulum_md
    assert to_unit("2 N.cm", md, "N.m") == 0.02
    assert to_unit("3 N.mm", md, "N.m") == 0.003
    assert to_unit("1.5 J", md, "N.m") == 1.5  # same BaseUnit exponents as N.m
    assert to_unit("5 deg", md, "rad") == pytest.approx(math.radians(5), rel=1e-15)
    assert to_unit("20 ms", md, "s") == 0.02
    assert to_unit(7, md, "m") == 7.0  # bare numbers are in the variable's unit
    assert to_unit("7", md, "m") == 7.0
    assert list(unit_conversions(md, "rad")) == ["rad", "deg"]


@pytest.mark.parametrize("value, unit, expected", [
    ("2 N.cm", "rad", "a unit of rad: one of rad, deg"),
    ("3 deg", None, "bare number"),
    ("1 furlong", "m", "a unit of m"),
    ("fast", "m", "a number or a string"),
    (True, "m", "a number or a string"),
    ("inf m", "m", "a finite number"),
])
def test_unit_errors(pendulum_md, value, unit, expected):
    with pytest.raises(UnitError, match=expected):
        to_unit(value, pendulum_md, unit)


def test_time_table():
    assert to_seconds(2) == 2.0
    assert to_seconds("1.5 min") == 90.0
    assert to_seconds("2 h") == 7200.0
    assert to_seconds("1 d") == 86400.0
    assert to_seconds("3 us") == 3e-6
    assert to_seconds("250 ms") == 0.25
    with pytest.raises(UnitError, match="time unit"):
        to_seconds("3 m")


def test_fmt():
    assert fmt(1e6) == "1000000"
    assert fmt(1e-6) == "1e-06"
    assert fmt(0.1) == "0.1"


# --- a valid scene -------------------------------------------------------------

def test_good_scene_values_are_converted():
    s = load_scene(DATA / "good.toml")
    assert s.title == "Two pendulums"
    assert s.reproduces == "nothing in particular"
    assert list(s.components) == ["pendulum", "other"]
    p = s.components["pendulum"]
    assert p.parameters["Q"] == 1000.0
    assert p.parameters["phi_start"] == pytest.approx(math.radians(5), rel=1e-15)
    assert p.parameters["L"] == pytest.approx(0.994, rel=1e-15)
    assert s.components["other"].parameters == {"phi_start": 0.1, "h_max": 0.02}
    assert p.fmu_path == fmu_file("Pendulum").resolve()
    assert p.sha256 == hashlib.sha256(fmu_file("Pendulum").read_bytes()).hexdigest()
    assert p.model_description.modelName == "Pendulum"
    assert p.variable("phi").causality == "output"
    assert s.connections == ()
    assert (s.experiment.start, s.experiment.stop) == (0.0, 60.0)
    m = s.master
    assert (m.step, m.order, m.extrapolation, m.event_time_tolerance) == (0.005, "jacobi", 2, 1e-6)
    assert m.max_step == 0.005  # defaults to the step
    assert (m.iterations, m.richardson, m.min_step) == (0, False, 1e-9)
    assert s.record.outputs == (("pendulum", "phi"), ("other", "energy"), ("pendulum", "Q"))
    assert s.record.interval == 0.01 and s.record.ticks == "pendulum"
    assert s.analysis == {"kind": "steady_state", "tolerance_s_per_day": 0.01, "max_periods": 400,
                          "amplitude_guess": pytest.approx(math.radians(5), rel=1e-15)}
    assert s.sweep.mode == "grid"
    q, phi = s.sweep.axes
    assert q.parameter == ("pendulum", "Q")
    assert q.values == pytest.approx((500.0, 1000.0, 2000.0), rel=1e-14)
    assert phi.values == pytest.approx((math.radians(2), math.radians(4)), rel=1e-15)
    points = s.points()
    assert len(points) == 6 and s.sweep.shape == (3, 2)
    assert points[1] == {("pendulum", "Q"): q.values[0], ("other", "phi_start"): phi.values[1]}
    assert [pl["kind"] for pl in s.plots] == ["sweep", "rate_errors"]  # a steady state draws no series
    assert s.plots[0]["file"] == "angles.png"
    assert len(s.sha256) == 64


def test_scene_is_frozen_and_variant_applies_a_point():
    s = load_scene(DATA / "good.toml")
    with pytest.raises(AttributeError):
        s.title = "x"
    v = s.variant({("pendulum", "Q"): 123.0, ("master", "step"): 0.002})
    assert v.components["pendulum"].parameters["Q"] == 123.0
    assert s.components["pendulum"].parameters["Q"] == 1000.0  # original untouched
    assert (v.master.step, v.master.max_step) == (0.002, 0.002)
    with pytest.raises(SceneError, match="experiment.stop"):
        s.variant({("experiment", "stop"): -1.0})


def test_defaults_record_every_output(tmp_path):
    f = tmp_path / "min.toml"
    f.write_text('[scene]\ntitle = "t"\n[components.p]\nfmu = "Pendulum"\n[experiment]\nstop = 1\n')
    s = load_scene(f)
    outputs = [v.name for v in s.components["p"].model_description.modelVariables if v.causality == "output"]
    assert s.record.outputs == tuple(("p", n) for n in outputs)
    assert s.record.interval is None and s.analysis is None and s.sweep is None
    assert s.plots == ({"kind": "outputs", "file": "outputs.png"},)  # the default plot of a time series
    assert s.master.step == 0.01 and s.master.order == "gauss-seidel" and s.master.event_location is True


def test_fmu_path_relative_to_scene(tmp_path):
    (tmp_path / "m").mkdir()
    (tmp_path / "m" / "P.fmu").write_bytes(fmu_file("Pendulum").read_bytes())
    f = tmp_path / "s.toml"
    f.write_text('[scene]\ntitle = "t"\n[components.p]\nfmu = "m/P.fmu"\n[experiment]\nstop = 1\n')
    assert load_scene(f).components["p"].fmu_path == (tmp_path / "m" / "P.fmu").resolve()


def test_valid_connections_with_drag(tmp_path):
    drag = FMU_DIR / "Drag.fmu"
    if not drag.exists():
        pytest.skip("Drag.fmu not built")
    f = tmp_path / "s.toml"
    f.write_text('connections = ["pendulum.w -> drag.w", "drag.tau -> pendulum.tau_drag"]\n'
                 '[scene]\ntitle = "t"\n[components.pendulum]\nfmu = "Pendulum"\n'
                 '[components.drag]\nfmu = "Drag"\n[experiment]\nstop = 1\n')
    s = load_scene(f)
    assert s.connections == (("pendulum", "w", "drag", "w", 1.0, 0.0, False),
                             ("drag", "tau", "pendulum", "tau_drag", 1.0, 0.0, False))
    src, src_var, dst, dst_var = s.connections[1][:4]
    assert (src, dst_var) == ("drag", "tau_drag")


def test_unconnected_input_can_be_set_but_not_a_connected_one(tmp_path):
    f = tmp_path / "s.toml"
    base = '[scene]\ntitle = "t"\n[components.p]\nfmu = "Pendulum"\nparameters = {{ tau_external = "{v}" }}\n' \
           '[components.q]\nfmu = "Pendulum"\n[experiment]\nstop = 1\n'
    f.write_text(base.format(v="1 N.cm"))
    assert load_scene(f).components["p"].parameters["tau_external"] == 0.01
    f.write_text('connections = ["q.tick_time -> p.tau_external"]\n' + base.format(v="1 N.cm"))
    e = error_of(f)
    assert "connections[0]" in str(e) and "also set in components.p.parameters.tau_external" in str(e)


# --- bad scenes ----------------------------------------------------------------

BAD = [
    # file, key named in the message, what the message must say
    ("bad_toml.toml", "line 5", "malformed TOML"),
    ("bad_top_key.toml", "experimnet", "did you mean experiment?"),
    ("bad_master_key.toml", "master.stepp", "did you mean step?"),
    ("bad_connections_place.toml", "components.other.connections", "must come before the first [table] header"),
    ("bad_fmu_name.toml", "components.pendulum.fmu", "cmake --build build"),
    ("bad_fmu_path.toml", "components.pendulum.fmu", "no such FMU file"),
    ("bad_fmu_garbage.toml", "components.pendulum.fmu", "not a zip archive"),
    ("bad_fmu_nomd.toml", "components.pendulum.fmu", "no modelDescription.xml"),
    ("bad_variable.toml", "components.pendulum.parameters.phi_strat", "did you mean phi_start"),
    ("bad_input_twice.toml", "connections[1]", "connected twice"),
    ("bad_output_to_output.toml", "connections[0]", "output connected to an output"),
    ("bad_input_source.toml", "connections[0]", "input used as a source"),
    ("bad_type_mismatch.toml", "connections[0]", "type mismatch: pendulum.tick_count is Integer"),
    ("bad_unit_mismatch.toml", "connections[0]", "unit mismatch: pendulum.phi is in rad, other.tau_external in N.m"),
    ("bad_unit_torque_for_angle.toml", 'components.pendulum.parameters.phi_start = "2 N.cm"', "a unit of rad"),
    ("bad_unit_dimensionless.toml", 'components.pendulum.parameters.Q = "3 deg"', "bare number"),
    ("bad_range.toml", 'components.pendulum.parameters.L = "-1 m"', "expected a value in [1e-06, 1000000] m"),
    ("bad_output_parameter.toml", "components.pendulum.parameters.phi", "is an output, not a parameter"),
    ("bad_stop.toml", "experiment.stop", "expected a time > experiment.start"),
    ("bad_time_unit.toml", "experiment.stop", "time unit"),
    ("bad_step.toml", "master.step", "expected a time > 0"),
    ("bad_extrapolation.toml", "master.extrapolation = 3", "0, 1 or 2"),
    ("bad_order.toml", 'master.order = "seidel"', '"gauss-seidel" or "jacobi"'),
    ("bad_record.toml", "record.outputs[0]", "has no variable phii (did you mean phi"),
    ("bad_sweep_param.toml", "sweep.axes[0].parameter", "has no variable QQ"),
    ("bad_sweep_empty.toml", "sweep.axes[0].values", "non-empty"),
    ("bad_sweep_num.toml", "sweep.axes[0].num = 0", "an integer from 1 to 1000000"),
    ("bad_sweep_log.toml", "sweep.axes[0].start", "> 0 for log spacing"),
    ("bad_analysis_kind.toml", "analysis.kind", "did you mean steady_state?"),
    ("bad_plot_key.toml", "plot[0].ylabel", "unknown key; allowed: file, kind, title, x, y"),
    ("bad_no_title.toml", "scene.title", "missing required key"),
]


def test_every_bad_fixture_is_in_the_table():
    assert sorted(f.name for f in DATA.glob("bad_*.toml")) == sorted(b[0] for b in BAD)


@pytest.mark.parametrize("name, key, expected", BAD, ids=[b[0] for b in BAD])
def test_bad_scene(name, key, expected):
    path = DATA / name
    e = error_of(path)
    msg = str(e)
    assert msg.startswith(f"{path}: "), msg
    assert key in msg, msg
    assert expected in msg, msg


@pytest.mark.parametrize("text, key, expected", [
    ('[scene]\ntitle = "t"\n[components."p/q"]\nfmu = "Pendulum"\n[experiment]\nstop = 1\n',
     "components.p/q", "without '/'"),
    ('[scene]\ntitle = "t"\n[components.master]\nfmu = "Pendulum"\n[experiment]\nstop = 1\n',
     "components.master", "reserved"),
    ('[scene]\ntitle = "t"\n[components.p]\nfmu = "Pendulum"\nparameters = { tick_count = 1.5 }\n'
     '[experiment]\nstop = 1\n', "components.p.parameters.tick_count", "not a parameter"),
    ('[scene]\ntitle = "t"\n[components.p]\nfmu = "Pendulum"\n[experiment]\nstop = 1\n[master]\n'
     'step = 0.1\nmax_step = 0.01\n', "master.max_step", "max_step >= step"),
    ('[scene]\ntitle = "t"\n[components.p]\nfmu = "Pendulum"\n[experiment]\nstop = 1\n[record]\nticks = "q"\n',
     'record.ticks = "q"', "the name of a component"),
    ('[scene]\ntitle = "t"\n[components.p]\nfmu = "Pendulum"\n[experiment]\nstop = 1\n[sweep]\nmode = "zip"\n'
     'axes = [{ parameter = "p.Q", values = [1, 2] }, { parameter = "p.L", values = [1] }]\n',
     "sweep.axes[1]", "equal length"),
    ('[scene]\ntitle = "t"\n[components.p]\nfmu = "Pendulum"\n[experiment]\nstop = 1\n[sweep]\n'
     'axes = [{ parameter = "p.phi", values = [1, 2] }]\n', "sweep.axes[0].parameter", "not a parameter"),
    ('[scene]\ntitle = "t"\n[components.p]\nfmu = "Pendulum"\n[experiment]\nstop = 1\n[sweep]\n'
     'axes = [{ parameter = "p.L", values = ["1 m", "-2 m"] }]\n', "sweep.axes[0].values[1]", "[1e-06, 1000000] m"),
    ('[scene]\ntitle = "t"\n[components.p]\nfmu = "Pendulum"\n[experiment]\nstop = 1\n[sweep]\n'
     'axes = [{ parameter = "master.step", values = ["1 ms", "0 ms"] }]\n', "sweep.axes[0].values[1]", "> 0"),
    ('[scene]\ntitle = "t"\n[components.p]\nfmu = "Pendulum"\n[experiment]\nstop = 1\n[master]\nmax_step = 0.01\n'
     '[sweep]\naxes = [{ parameter = "master.step", values = [0.001, 0.1] }]\n', "sweep", "max_step >= step"),
    ('[scene]\ntitle = "t"\n[components.p]\nfmu = "Pendulum"\n[experiment]\nstop = 1\n[analysis]\n'
     'kind = "steady_state"\nmax_periods = 0\n', "analysis.max_periods = 0", "an integer in [2, 1,000]"),
    ('[scene]\ntitle = "t"\n[components.p]\nfmu = "Pendulum"\n[experiment]\nstop = 1\n[[plot]]\nkind = "sweep"\n'
     'file = "../x.png"\n', "plot[0].file", "without a directory"),
    ('[scene]\ntitle = "t"\n[components.p]\nfmu = "Pendulum"\nparameters = { Q = nan }\n[experiment]\nstop = 1\n',
     "components.p.parameters.Q = nan", "finite"),
    ('[scene]\ntitle = "t"\n[experiment]\nstop = 1\n', "components", "missing required table"),
])
def test_more_bad_scenes(tmp_path, text, key, expected):
    f = tmp_path / "x.toml"
    f.write_text(text)
    msg = str(error_of(f))
    assert msg.startswith(f"{f}: ") and key in msg and expected in msg, msg


def test_missing_scene_file(tmp_path):
    msg = str(error_of(tmp_path / "nope.toml"))
    assert "nope.toml" in msg and "no such scene file" in msg


# --- overrides -------------------------------------------------------------------

def test_parse_override():
    assert parse_override("p.Q=2.5") == ("p", "Q", 2.5)
    assert parse_override('p.phi_start="2.5 deg"') == ("p", "phi_start", "2.5 deg")
    assert parse_override("p.phi_start=2.5 deg") == ("p", "phi_start", "2.5 deg")
    assert parse_override("master.event_location=false") == ("master", "event_location", False)
    with pytest.raises(ValueError, match="expected instance.parameter=value"):
        parse_override("p.Q")
    with pytest.raises(ValueError, match="expected instance.parameter=value"):
        parse_override("Q=1")


def test_overrides_apply():
    s = load_scene(DATA / "good.toml", ["pendulum.Q=500", "other.phi_start=2.5 deg", "master.step=0.01",
                                        'experiment.stop="10 s"', "analysis.max_periods=10"])
    assert s.components["pendulum"].parameters["Q"] == 500.0
    assert s.components["other"].parameters["phi_start"] == pytest.approx(math.radians(2.5), rel=1e-15)
    assert (s.master.step, s.master.max_step) == (0.01, 0.01)
    assert s.experiment.stop == 10.0
    assert s.analysis["max_periods"] == 10
    assert len(s.overrides) == 5


@pytest.mark.parametrize("override, expected", [
    ("pendulum.L=-1", "--set pendulum.L = -1: expected a value in [1e-06, 1000000] m"),
    ("pendulum.nope=1", "--set pendulum.nope: pendulum (Pendulum) has no variable nope"),
    ("pendlum.L=1", "--set pendlum.L: no component named pendlum (did you mean pendulum?)"),
    ("pendulum.L", "--set pendulum.L: expected instance.parameter=value"),
    ("master.stpe=1", "--set master.stpe: unknown key (did you mean step?)"),
    ("master.event_prediction=1", "--set master.event_prediction = 1: expected true or false"),
    ("sweep.mode=zip", "--set sweep.mode: cannot be set from the command line"),
    ("experiment.stop=-5 s", '--set experiment.stop = "-5 s": expected a time > experiment.start'),
    ("pendulum.phi=1", "--set pendulum.phi: Pendulum.phi is an output, not a parameter"),
])
def test_bad_overrides(override, expected):
    path = DATA / "good.toml"
    msg = str(error_of(path, [override]))
    assert msg.startswith(f"{path}: ") and expected in msg, msg


# --- registry ---------------------------------------------------------------------

def test_register_analysis_kind(tmp_path):
    def convert(t):
        if "horizon" in t and not isinstance(t["horizon"], (int, float)):
            raise Invalid("horizon", "a number")
        return {k: float(v) for k, v in t.items()}

    register_analysis("demo_kind", {"horizon"}, convert)
    try:
        f = tmp_path / "s.toml"
        f.write_text('[scene]\ntitle = "t"\n[components.p]\nfmu = "Pendulum"\n[experiment]\nstop = 1\n'
                     '[analysis]\nkind = "demo_kind"\nhorizon = 3\n')
        assert load_scene(f).analysis == {"kind": "demo_kind", "horizon": 3.0}
        f.write_text(f.read_text().replace("horizon = 3", 'horizon = "x"'))
        assert 'analysis.horizon = "x": expected a number' in str(error_of(f))
    finally:
        del ANALYSIS_KEYS["demo_kind"]
        _ANALYSIS_CONVERT.pop("demo_kind", None)


def test_docs_example_validates(tmp_path):
    import re

    if not (FMU_DIR / "GrasshopperEscapement.fmu").exists():
        pytest.skip("GrasshopperEscapement.fmu not built")
    doc = (Path(__file__).resolve().parents[1] / "docs" / "scenes.md").read_text()
    f = tmp_path / "example.toml"
    f.write_text(re.search(r"```toml\n(.*?)```", doc, re.S).group(1))
    s = load_scene(f)
    assert len(s.components) == 2 and len(s.connections) == 3
    assert s.components["escapement"].parameters["torque"] == pytest.approx(0.004, rel=1e-15)
    assert s.sweep.shape == (2, 4)


# --- master settings: what the master refuses, validate refuses -----------------

CORE = Path(__file__).resolve().parents[1] / "scenarios" / "core_grasshopper.toml"


@pytest.mark.parametrize("how", ["file", "set", "sweep"])
@pytest.mark.parametrize("values, key", [
    ({"iterations": 2, "richardson": "true"}, "master.iterations"),
    ({"iterations": 1, "richardson": "true", "event_location": "false"}, "master.iterations"),
])
def test_a_combination_the_master_refuses_is_refused_at_validate(tmp_path, how, values, key):
    """Every combination of master settings that MasterSettings refuses
    (issue 28, E: richardson with iterations passed validate, and the run's
    line named no file) is refused when the scene loads, naming the file and
    the key, whether it comes from the file, a --set or a sweep point."""
    text = CORE.read_text()
    overrides = ()
    if how == "file":
        text = text.replace("[master]\n", "[master]\n" + "".join(f"{k} = {v}\n" for k, v in values.items()))
        text = text.replace("event_location = true\n", "", 1) if "event_location" in values else text
    elif how == "set":
        overrides = tuple(f"master.{k}={v}" for k, v in values.items())
    else:
        rest = {k: v for k, v in values.items() if k != "iterations"}
        text = text.replace("[master]\n", "[master]\n" + "".join(f"{k} = {v}\n" for k, v in rest.items()))
        text = text.replace("event_location = true\n", "", 1) if "event_location" in values else text
        text += f'\n[sweep]\naxes = [{{ parameter = "master.iterations", values = [0, {values["iterations"]}] }}]\n'
    scene = tmp_path / "s.toml"
    scene.write_text(text)
    e = error_of(scene, overrides)
    assert e.path == str(scene), str(e)
    assert key in str(e) and "richardson" in str(e), str(e)
