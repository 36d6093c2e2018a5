"""The instance contract (clockwork/fmi/contract.py): the master never asks
which FMI version or interface an instance has, and every kind of FMU
answers the contract's calls alike.

1. A structural check over the master's modules (clockwork/engine/*.py but
   the one factory, instances.py): no read of ``.fmi_version`` or
   ``.interface``, no isinstance (or ``type(x) is``) against a face class,
   no face class imported.
2. The contract's behaviour on every kind of FMU the repository builds:
   FMI 1.0, 2.0 and 3.0 Co-Simulation, FMI 1.0, 2.0 and 3.0 Model Exchange, and
   FMI 3.0 with arrays.
"""

from __future__ import annotations

import ast
import ctypes
import math
from ctypes import c_double, c_int, c_uint
from pathlib import Path

import pytest

from clockwork.engine.instances import make_instance
from clockwork.errors import SimulationEnded
from clockwork.fmi.calls import DISCARD, OK, WARNING
from clockwork.fmi.contract import CORE_CALLS, Instance
from clockwork.paths import core_library
from cwtest import FMU_DIR, ROOT, test_fmu
from fmi3_linear import fmu  # noqa: F401 (a fixture: the FMI 3.0 test FMU with arrays)

FACES = {"Instance1", "Instance2", "Instance3", "MEInstance", "ModelExchange1", "ModelExchange2", "ModelExchange3"}
MASTER_MODULES = sorted(p for p in (ROOT / "clockwork" / "engine").glob("*.py") if p.name != "instances.py")


# 1. The master never asks --------------------------------------------------------------------------------


def _problems(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(), str(path))
    found = []
    for node in ast.walk(tree):
        where = f"{path.relative_to(ROOT)}:{getattr(node, 'lineno', 0)}"
        if isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Load):
            # settings.fmi_version is the scene's choice of the bundled FMUs'
            # build (fmus/ or fmus/fmi3/), a setting, not an FMU's version.
            setting = (node.attr == "fmi_version" and isinstance(node.value, ast.Name)
                       and node.value.id == "settings")
            if node.attr in ("fmi_version", "interface") and not setting:
                found.append(f"{where}: reads .{node.attr}")
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in (
                "isinstance", "issubclass") and len(node.args) == 2:
            named = {n.id for n in ast.walk(node.args[1]) if isinstance(n, ast.Name)}
            named |= {n.attr for n in ast.walk(node.args[1]) if isinstance(n, ast.Attribute)}
            if named & FACES:
                found.append(f"{where}: {node.func.id} against {', '.join(sorted(named & FACES))}")
        if isinstance(node, ast.Compare) and isinstance(node.left, ast.Call) and isinstance(
                node.left.func, ast.Name) and node.left.func.id == "type":
            named = {n.id for c in node.comparators for n in ast.walk(c) if isinstance(n, ast.Name)}
            if named & FACES:
                found.append(f"{where}: type() compared with {', '.join(sorted(named & FACES))}")
        if isinstance(node, ast.ImportFrom):
            imported = {a.name for a in node.names} & (FACES - {"MEInstance"})
            if imported:
                found.append(f"{where}: imports the face {', '.join(sorted(imported))}")
    return found


def test_the_masters_modules_never_ask_the_version_or_the_interface():
    assert len(MASTER_MODULES) > 10
    problems = [p for path in MASTER_MODULES for p in _problems(path)]
    assert problems == []


def test_the_compiled_master_never_asks_the_version():
    """The C master (src_c/master) calls every FMU through pointers its face
    hands over (the ports', the adapters' cw1_*/cw3_*, cw_me.c's table of
    version-shaped calls): no field or variable names a version in its code
    (comments aside; the FMI functions fmi*GetVersion are the FMU's own
    names)."""
    import re

    found = []
    for path in sorted((ROOT / "src_c" / "master").glob("*.[ch]")):
        code = re.sub(r"/\*.*?\*/", "", path.read_text(), flags=re.S)
        code = re.sub(r"//[^\n]*", "", code)
        found += [f"{path.name}: {m.group(0)}" for m in re.finditer(r"\b[a-z_0-9]*version[a-z_0-9]*\b", code)]
    assert found == []


def test_the_check_finds_what_it_looks_for(tmp_path):
    """The structural check itself: each kind of question it must refuse."""
    bad = tmp_path / "clockwork" / "engine" / "bad.py"
    bad.parent.mkdir(parents=True)
    bad.write_text("from ..fmi.cs3 import Instance3\n"
                   "def f(inst, p, settings):\n"
                   "    a = inst.fmi_version == 3\n"
                   "    b = p.inst.interface\n"
                   "    c = isinstance(inst, (Instance3, MEInstance))\n"
                   "    d = type(inst) is Instance3\n"
                   "    e = settings.fmi_version\n")
    import test_contract
    old = test_contract.ROOT
    test_contract.ROOT = tmp_path
    try:
        found = _problems(bad)
    finally:
        test_contract.ROOT = old
    assert sorted(f.split(": ", 1)[1] for f in found) == sorted([
        "imports the face Instance3", "reads .fmi_version", "reads .interface",
        "isinstance against Instance3, MEInstance", "type() compared with Instance3"])


def test_no_face_subclasses_another():
    """The faces are siblings under the contract: none is the base of another."""
    from clockwork.engine.model_exchange import MEInstance
    from clockwork.fmi.cs1 import Instance1
    from clockwork.fmi.cs2 import Instance2
    from clockwork.fmi.cs3 import Instance3

    faces = (Instance1, Instance2, Instance3, MEInstance)
    for face in faces:
        assert issubclass(face, Instance)
        assert not any(issubclass(face, other) for other in faces if other is not face), face
    # No method of one face is another face's function (borrowed by assignment).
    for face in faces:
        for name, value in vars(face).items():
            if callable(value):
                owner = getattr(value, "__qualname__", "").split(".")[0]
                assert owner in (face.__name__, "") or owner not in {f.__name__ for f in faces}, (face, name)


# 2. Every kind answers the contract ------------------------------------------------------------------------

KINDS = {
    "fmi1-cs": lambda: test_fmu("fmi1/Pendulum"),
    "fmi2-cs": lambda: FMU_DIR / "Pendulum.fmu",
    "fmi3-cs": lambda: FMU_DIR / "fmi3" / "Pendulum.fmu",
    "fmi1-me": lambda: test_fmu("fmi1me/MeLag"),
    "fmi2-me": lambda: test_fmu("MeLag"),
    "fmi3-me": lambda: test_fmu("fmi3/MeLag"),
}
OWN_PREFIX = {"fmi1-cs": "fmi", "fmi1-me": "fmi",
              "fmi2-cs": "fmi2", "fmi3-cs": "fmi3", "fmi2-me": "fmi2", "fmi3-me": "fmi3",
              "fmi3-arrays": "fmi3"}


@pytest.fixture(params=[*KINDS, "fmi3-arrays"])
def kind(request):
    if request.param == "fmi3-arrays":
        return request.param, Path(request.getfixturevalue("fmu"))
    path = Path(KINDS[request.param]())
    if not path.exists():
        pytest.fail(f"{path} is missing: build the FMUs first (cmake --build build)")
    return request.param, path


def _started(name, path):
    inst = make_instance(name, path)
    inst.instantiate()
    inst.setup(0.0, {})
    inst.exit_init()
    return inst


def _reals(inst, causality):
    return [n for n, v in inst.variables.items()
            if v.type in ("Real", "Float64") and v.causality == causality and not v.shape]


def test_capabilities_are_plain_attributes_and_names_are_the_faces_own(kind):
    label, path = kind
    inst = make_instance("x", path)
    assert isinstance(inst, Instance)
    for attr in ("can_interpolate_inputs", "outputs_after_inputs", "can_get_set_state", "has_event_mode"):
        assert type(getattr(inst, attr)) is bool, attr
    assert type(inst.max_output_derivative_order) is int and inst.max_output_derivative_order >= 0
    assert not hasattr(inst, "fmi_version")  # the master has nothing to ask
    # Each face names its own functions: no other version's prefix in any name.
    names = [inst.named(c) for c in ("doStep", "getReal", "setReal", "getState", "setState", "reset", "setup",
                                     "enterInit", "exitInit", "setValues", "getInteger")]
    others = {"fmi": ("fmi2", "fmi3"), "fmi2": ("fmi3",), "fmi3": ("fmi2",)}[OWN_PREFIX[label]]
    assert not [n for n in names if n.startswith(others)], names
    assert any(n.startswith(OWN_PREFIX[label]) for n in names)


def test_values_in_and_out_the_step_and_the_core_calls(kind):
    label, path = kind
    inst = _started("x", path)
    try:
        comp = inst.component
        outputs = _reals(inst, "output")[:2]
        assert outputs
        vr = (c_uint * len(outputs))(*[inst.variables[n].vr for n in outputs])
        out = (c_double * len(outputs))()
        assert inst.c_getReal(comp, vr, len(outputs), out) <= WARNING
        assert list(out) == inst.get_real(outputs)
        inputs = _reals(inst, "input")[:1]
        if inputs:
            ivr = (c_uint * 1)(inst.variables[inputs[0]].vr)
            assert inst.c_setReal(comp, ivr, 1, (c_double * 1)(0.25)) <= WARNING
        assert inst.c_doStep(comp, 0.0, 0.01, 0) <= WARNING
        assert inst.c_getReal(comp, vr, len(outputs), out) <= WARNING
        assert all(math.isfinite(x) for x in out)
        assert inst.ended(0.01) is None  # nothing asked to end
        ev = inst.time_events
        if ev is not None:  # announced time events: what the master and the core read
            assert not ev.terminated and ev.next_event_time > 0.0
        # The compiled core's calls: a pointer and one C function per contract call.
        lib = ctypes.CDLL(str(core_library()))
        first, calls = inst.core_calls(lib)
        assert first and len(calls) == len(CORE_CALLS) and all(calls)
    finally:
        inst.free()
    assert inst.freed


def test_state_save_restore_repeats_a_step_to_the_bit(kind):
    label, path = kind
    inst = _started("x", path)
    try:
        if not inst.can_get_set_state:  # FMI 1.0, and the arrays FMU, which does not declare it
            assert label in ("fmi1-cs", "fmi1-me", "fmi3-arrays")
            if label.startswith("fmi1"):
                with pytest.raises(Exception, match="FMI 1.0 has no"):
                    inst.save_state(0.0)
            return
        comp = inst.component
        outputs = _reals(inst, "output")[:2]
        vr = (c_uint * len(outputs))(*[inst.variables[n].vr for n in outputs])
        inst.save_state(0.0)
        assert inst.c_doStep(comp, 0.0, 0.05, 0) <= WARNING
        first = inst.get_real(outputs)
        inst.restore_state(0.0)
        assert inst.c_doStep(comp, 0.0, 0.05, 0) <= WARNING
        again = (c_double * len(outputs))()
        assert inst.c_getReal(comp, vr, len(outputs), again) <= WARNING
        assert list(again) == first
    finally:
        inst.free()


def test_output_derivatives_up_to_the_declared_order(kind):
    label, path = kind
    inst = _started("x", path)
    try:
        outputs = _reals(inst, "output")
        assert inst.c_doStep(inst.component, 0.0, 0.01, 0) <= WARNING
        order = inst.max_output_derivative_order
        if order:  # some output has them (not every one need)
            assert [n for n in outputs if inst.output_derivatives([n], 1) is not None]
        assert inst.output_derivatives(outputs[:1], order + 1) is None
    finally:
        inst.free()


@pytest.mark.parametrize("version", ["", "fmi3/", "fmi1me/"])
def test_a_model_exchange_fmu_asks_to_end_through_the_contract(version):
    """MeBall with n_stop: its terminateSimulation is a discarded step and
    ``ended`` (FMI 1.0's, 2.0's and 3.0's Model Exchange alike)."""
    inst = make_instance("b", test_fmu(version + "MeBall"))
    inst.instantiate()
    inst.setup(0.0, {"n_stop": 1})
    inst.exit_init()
    try:
        t, h = 0.0, 0.05
        while t < 5.0:
            st = inst.c_doStep(inst.component, t, h, 0)
            if st == DISCARD:
                break
            assert st == OK
            t += h
        assert st == DISCARD
        end = inst.ended(t, h)
        assert isinstance(end, SimulationEnded) and t <= end.fmu_time <= t + h
    finally:
        inst.free()


def test_fmi1_has_no_end_status():
    inst = make_instance("p", test_fmu("fmi1/Pendulum"))
    assert inst.terminated() is False and inst.last_successful_time() is None
    assert inst.time_events is None


def test_an_fmi3_fmu_refuses_polynomial_inputs_without_intermediate_update():
    inst = make_instance("p", FMU_DIR / "fmi3" / "Pendulum.fmu")
    text = inst.polynomial_inputs_refusal("master.extrapolation = 0")
    assert text and "FMI 3.0" in text and "master.extrapolation = 0" in text
    assert make_instance("p", FMU_DIR / "Pendulum.fmu").polynomial_inputs_refusal("x") is None


def test_the_core_calls_are_in_the_contracts_order():
    """compiled.py hands core_calls to the port's fields in CORE_CALLS's order."""
    from clockwork.engine.compiled import _Port

    fields = [name for name, _ in _Port._fields_]
    assert fields[1:1 + len(CORE_CALLS)] == list(CORE_CALLS)


def test_input_derivatives_by_the_contract_where_a_face_takes_them():
    inst = _started("p", FMU_DIR / "Pendulum.fmu")
    try:
        assert inst.can_interpolate_inputs
        vr = (c_uint * 1)(inst.variables["tau_escapement"].vr)
        assert inst.c_setInputDerivatives(inst.component, vr, 1, (c_int * 1)(1), (c_double * 1)(0.5)) <= WARNING
        assert inst.c_doStep(inst.component, 0.0, 0.01, 0) <= WARNING
    finally:
        inst.free()
