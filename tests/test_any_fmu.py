"""Generic FMI 2.0 Co-Simulation correctness (issue 20): what any FMU and
any system file may hold, on both engines.

Link transformations and unit conversion, the names SSP and FMI allow,
direct feedthrough from dependencies on inputs only, every variable type,
an FMU that ends the simulation, the DefaultExperiment tolerance, FMU log
messages, and the extrapolation order an FMU accepts.
"""

from __future__ import annotations

import math

import pytest

from clockwork.engine import MasterSettings, System
from clockwork.engine.names import instance_name_problem, split_ref
from clockwork.engine.wiring import Link, parse_link
from clockwork.errors import SceneError
from clockwork.scene import load_scene
from clockwork.scene.units import link_conversion
from cwtest import run_cli

ENGINES = ("python", "compiled")


# -- link transformations ------------------------------------------------------

@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("factor, offset", [(2.0, 0.0), (1.0, 0.25), (-0.5, 1e-3)])
def test_an_input_receives_factor_times_output_plus_offset(engine, factor, offset):
    links = [Link("pendulum", "w", "drag", "w", factor, offset), Link("drag", "tau", "pendulum", "tau_drag")]
    comps = {"pendulum": ("Pendulum", dict(Q=1000.0, phi_start=0.1)), "drag": ("Drag", dict(c1=1e-4))}
    with System(comps, links, MasterSettings(step=0.01, engine=engine)) as s:
        for t in (0.0, 0.37, 1.0):
            s.master.run_until(t) if t else None
            w = s.value("pendulum", "w")
            assert s.value("drag", "w") == factor * w + offset
            assert s.output("drag", "tau") == -1e-4 * (factor * w + offset)


@pytest.mark.parametrize("settings", [dict(step=0.01), dict(step=0.02, extrapolation=2),
                                      dict(step=0.02, extrapolation=1, order="jacobi")])
def test_transformed_links_give_the_same_bits_on_both_engines(settings):
    comps = {"pendulum": ("Pendulum", dict(Q=1000.0, phi_start=0.1)),
             "escapement": ("GrasshopperEscapement", dict(torque=4e-3, phi_r=0.035)),
             "drag": ("Drag", dict(c1=2e-5))}
    links = [Link("pendulum", "phi", "escapement", "phi", 1.0, 1e-4), Link("pendulum", "w", "escapement", "w"),
             Link("escapement", "tau", "pendulum", "tau_escapement", 0.9),
             Link("pendulum", "w", "drag", "w", 3.0, -0.01), Link("drag", "tau", "pendulum", "tau_drag")]
    runs = []
    for engine in ENGINES:
        with System(comps, links, MasterSettings(engine=engine, **settings)) as s:
            s.master.run_until(3.0)
            runs.append((s.master.t, list(s.master.ports.buffer), s.master.stats))
    assert runs[0] == runs[1]


class _Unit:
    def __init__(self, name, factor=1.0, offset=0.0, **exponents):
        self.name = name
        self.baseUnit = type("Base", (), dict(factor=factor, offset=offset, **exponents))()
        self.displayUnits = []


class _Md:
    def __init__(self, *units):
        self.unitDefinitions = list(units)


def test_unit_conversion_comes_from_each_fmus_base_units():
    # Spellings meet by their SI base: Nm/A in one FMU, N.m/A in the other.
    a, b = _Md(_Unit("Nm/A", kg=1, m=2, s=-2, A=-1)), _Md(_Unit("N.m/A", kg=1, m=2, s=-2, A=-1))
    assert link_conversion(a, "Nm/A", b, "N.m/A") == (1.0, 0.0)
    # Scaled and shifted units: degC -> K -> degF.
    c = _Md(_Unit("degC", 1.0, 273.15, K=1))
    f = _Md(_Unit("degF", 5.0 / 9.0, 273.15 - 32.0 * 5.0 / 9.0, K=1))
    factor, offset = link_conversion(c, "degC", f, "degF")
    assert factor * 100.0 + offset == pytest.approx(212.0, abs=1e-12)
    assert factor * -40.0 + offset == pytest.approx(-40.0, abs=1e-12)
    # Different dimensions, or a unit an FMU does not define: no conversion.
    assert link_conversion(c, "degC", a, "Nm/A") is None
    assert link_conversion(c, "degC", _Md(), "K") is None


# -- names ---------------------------------------------------------------------

@pytest.mark.parametrize("name", ["0001_em", "edrive-mass", "sub.comp", "a b", "Ä"])
def test_ssp_and_fmi_instance_names_are_allowed(name):
    assert instance_name_problem(name) is None


@pytest.mark.parametrize("name", ["", " p", "p.", "a/b", "a\\b", "a->b", "a\nb"])
def test_names_that_cannot_be_an_instance_are_refused(name):
    assert instance_name_problem(name)


def test_references_split_at_the_longest_instance_name_that_fits():
    known = {"sub": {"comp.x"}, "sub.comp": {"der(x)", "MLoad.k", "a[1]"}}
    assert split_ref("sub.comp.der(x)", known) == ("sub.comp", "der(x)")
    assert split_ref("sub.comp.MLoad.k", known) == ("sub.comp", "MLoad.k")
    assert split_ref("sub.comp.a[1]", known) == ("sub.comp", "a[1]")
    assert split_ref("sub.comp.x", known) == ("sub", "comp.x")  # the longer name has no such variable
    assert split_ref("other.x", known) is None
    assert parse_link("sub.comp.der(x) -> sub.comp.x", known) == Link("sub.comp", "der(x)", "sub", "comp.x")


SCENE = """
connections = ["{a}.w -> {b}.w", "{b}.tau -> {a}.tau_drag"]
[scene]
title = "names"
[components."{a}"]
fmu = "Pendulum"
parameters = {{ Q = 500 }}
[components."{b}"]
fmu = "Drag"
[experiment]
stop = 0.1
[record]
outputs = ["{a}.phi", "{b}.tau"]
"""


@pytest.mark.parametrize("a, b", [("0001_em", "edrive-mass"), ("sub.comp", "sub"), ("x.y.z", "x.y")])
def test_a_scene_with_such_names_loads_sets_and_runs(capsys, tmp_path, a, b):
    f = tmp_path / "names.toml"
    f.write_text(SCENE.format(a=a, b=b))
    scene = load_scene(f, [f"{a}.Q=700", f"{b}.c1=1e-3"])
    assert scene.components[a].parameters["Q"] == 700.0
    assert scene.components[b].parameters["c1"] == 1e-3
    assert [tuple(c[:4]) for c in scene.connections] == [(a, "w", b, "w"), (b, "tau", a, "tau_drag")]
    assert scene.record.outputs == ((a, "phi"), (b, "tau"))
    code, out, err = run_cli(capsys, ["run", f, "--out", tmp_path / "out", "--no-progress"])
    assert code == 0, err
    header = (tmp_path / "out" / "timeseries.csv").read_text().splitlines()[0]
    assert header.split(",") == ["time", f"{a}.phi", f"{b}.tau"]
