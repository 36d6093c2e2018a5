"""ModelStructure dependencies (FMI 2.0 Sec. 2.2.8) against what the
equations actually read.

For every FMU and a few operating points, each Known is perturbed alone and
the outputs are read again at the same time instant:

- Initialization Mode (InitialUnknowns): the Knowns are the inputs and the
  parameters (initial="exact");
- right after fmi2ExitInitializationMode and after one fmi2DoStep (Outputs):
  the Knowns are the inputs.

An output that changes (bit for bit) although the Known is not among its
declared dependencies is an error: a master would order or break a loop on
wrong information. A declared dependency must show up at one operating
point at least, so that the declarations stay exact rather than merely safe.
"""

from __future__ import annotations

import pytest

from cwtest import fmu_file
from fmu_driver import OK, FmuError, Instance, unpack

# (parameters, inputs) per operating point, chosen so that every declared
# dependency is active somewhere (a torque input for the mass, a velocity for
# the damping, each escapement profile, a pending noise renewal, ...).
POINTS = {
    "Pendulum": [
        ({}, {"tau_external": 0.01}),
        ({"phi_start": -0.3, "w_start": 0.5, "Q": 50.0}, {"tau_drag": -0.02, "g_factor": 1.2}),
        ({"phi_start": 0.2, "w_start": 0.3, "bob_radius": 0.03, "alpha": 1e-5, "bob_density": 2000.0},
         {"tau_external": 0.01, "rho_air": 1.2, "mu_air": 1.8e-5, "temperature": 300.0}),
    ],
    "Drag": [({"c1": 0.01, "c2": 0.02}, {"w": 0.3}),
             ({"bob_radius": 0.03}, {"w": 0.3, "rho_air": 1.2, "mu_air": 1.8e-5})],
    "Air": [({}, {}), ({"x_CO2": 0.0005}, {"pressure": 95000.0, "temperature": 300.0, "humidity": 0.8})],
    "ChronometerEscapement": [({}, {"phi": 0.0, "w": 0.2})],
    "GrasshopperEscapement": [
        ({}, {}),
        ({"profile": 1, "velocity_gain": 2.0}, {"phi": 0.02, "w": 0.3, "vibration_velocity": 0.1}),
        ({"profile": 3, "noise_rms": 0.1}, {"phi": -0.1, "w": -0.2}),
        ({"profile": 2}, {"phi": 0.1, "w": 0.1}),
    ],
    "MechanismVibration": [({"a2_start": 1e-3, "a2dot_start": 0.01}, {"a1": 0.1})],
    "AveragedPendulum": [
        ({"phase_start": 0.3}, {"drive": 0.001}),
        ({"escapement": 1, "phi_1": 0.05}, {"drive": 0.002}),
        ({"escapement": 1, "phi_1": 0.05, "amplitude_start": 0.04}, {"drive": 0.002}),
    ],
}
STEP = {"AveragedPendulum": 2.0}


def candidates(var, x):
    """Perturbed values of a Known inside its declared range."""
    lo = float(var.min) if var.min is not None else -float("inf")
    hi = float(var.max) if var.max is not None else float("inf")
    if var.type == "Boolean":
        return [not x]
    if var.type == "Integer":
        ints = range(int(lo), int(hi) + 1) if hi - lo <= 4 else (x - 1, x + 1)
        return [k for k in ints if k != x and lo <= k <= hi]
    values = (x + 0.011, x - 0.37, 1.7 * x + 0.9, x - 2.3, 0.5 * x)
    return [v for v in values if v != x and lo <= v <= hi]


def declared(unknowns):
    out = {}
    for u in unknowns:
        assert u.dependencies is not None, f"{u.variable.name}: dependencies not declared"
        out[u.variable.name] = {d.name for d in u.dependencies}
    return out


def probe(p: Instance, outputs, knowns, seen):
    """Perturb each Known from the instance's current state; record in
    seen[(output, known)] whether the output moved."""
    base = p.get_many(outputs)
    saved = p.get_state()
    try:
        for known in knowns:
            for value in candidates(p.vars[known], p.get(known)):
                assert p.set_state(saved) == OK, p.log_text()
                if p.set(**{known: value}) != OK:
                    continue
                try:
                    now = p.get_many(outputs)
                except FmuError:  # outside what the model can represent
                    continue
                for name, b, n in zip(outputs, base, now):
                    seen.setdefault((name, known), False)
                    if b != n:
                        seen[(name, known)] = True
        assert p.set_state(saved) == OK
    finally:
        p.free_state(saved)


def compare(seen, deps, when):
    wrong = sorted(f"{o} <- {k}" for (o, k), moved in seen.items() if moved and k not in deps[o])
    assert not wrong, f"{when}: outputs change with undeclared Knowns: {wrong}"
    tried = {k for _, k in seen}
    idle = sorted(f"{o} <- {k}" for o, ks in deps.items() for k in ks
                  if k in tried and not seen.get((o, k)))
    assert not idle, f"{when}: declared dependencies never seen at any operating point: {idle}"


@pytest.mark.parametrize("model", sorted(POINTS))
def test_initial_unknowns_dependencies(model):
    fmu = fmu_file(model)
    md, _ = unpack(fmu)
    deps = declared(md.initialUnknowns)
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    assert sorted(deps) == sorted(outputs)
    knowns = [v.name for v in md.modelVariables if v.causality in ("parameter", "input")]
    seen: dict = {}
    for params, inputs in POINTS[model]:
        with Instance(fmu, initialize=False) as p:
            assert p.setup() == OK and p.enter_init() == OK
            assert p.set(**params, **inputs) == OK, p.log_text()
            probe(p, outputs, knowns, seen)
    compare(seen, deps, f"{model} in Initialization Mode")


@pytest.mark.parametrize("model", sorted(POINTS))
def test_output_dependencies(model):
    fmu = fmu_file(model)
    md, _ = unpack(fmu)
    deps = declared(md.outputs)
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    inputs = [v.name for v in md.modelVariables if v.causality == "input"]
    for when in ("after initialization", "after one step"):
        seen: dict = {}
        for params, values in POINTS[model]:
            with Instance(fmu, params, values) as p:
                if when == "after one step":
                    p.advance(STEP.get(model, 0.01))
                probe(p, outputs, inputs, seen)
        compare(seen, deps, f"{model} {when}")


@pytest.mark.parametrize("model", sorted(POINTS))
def test_state_outputs_close_no_loop_in_initialization(model):
    """An output without feedthrough at communication points needs no input
    in Initialization Mode either, unless the model derives its initial
    discrete state from the inputs (the grasshopper's mode)."""
    md, _ = unpack(fmu_file(model))
    outputs = declared(md.outputs)
    initial = declared(md.initialUnknowns)
    inputs = {v.name for v in md.modelVariables if v.causality == "input"}
    for name, deps in outputs.items():
        if not deps and model != "GrasshopperEscapement":
            assert not initial[name] & inputs, name


@pytest.mark.parametrize("model", sorted(POINTS))
def test_linear_dependency_kinds(model):
    """dependenciesKind other than "dependent" claims a linear factor
    (FMI 2.0 Sec. 2.2.8): the output's change must scale with the input's."""
    fmu = fmu_file(model)
    md, _ = unpack(fmu)
    linear = [(u.variable.name, d.name) for u in md.outputs
              for d, kind in zip(u.dependencies or [], u.dependenciesKind or [])
              if kind != "dependent"]
    for params, values in POINTS[model]:
        with Instance(fmu, params, values) as p:
            saved = p.get_state()
            for out, known in linear:
                assert p.set_state(saved) == OK
                u0 = p.get(known)
                base = p.get(out)
                changes = []
                for du in (1e-3, 2e-3, -5e-3):
                    assert p.set_state(saved) == OK
                    assert p.set(**{known: u0 + du}) == OK
                    changes.append((p.get(out) - base) / du)
                assert changes[0] != 0.0, (out, known)
                for c in changes[1:]:
                    assert c == pytest.approx(changes[0], rel=1e-9, abs=1e-300), (out, known, changes)
            assert p.set_state(saved) == OK
            p.free_state(saved)
