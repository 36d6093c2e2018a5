"""The ctypes mirrors of the compiled core's structs are checked field by
field against the layouts the core exports (fmi/layout.py,
src_c/master/cw_layout.h), so a mirror that differs in any one field is
refused at load, not only one of another size."""

import ast
import ctypes
import re
from pathlib import Path

import pytest

from clockwork.engine import compiled, compiled_clocks, cvode
from clockwork.fmi import layout
from clockwork.fmi.cs1 import _Fmi1
from clockwork.fmi.cs3 import _Events
from clockwork.engine.me_group import _Group
from clockwork.engine.model_exchange import _ME

MIRRORS = [("cw_layout", "port", compiled._Port), ("cw_layout", "master", compiled._Master),
           ("cw_layout", "recorder", compiled._Recorder), ("cw_layout", "marks", compiled._Marks),
           ("cw_layout", "loop", compiled._Loop), ("cw_layout", "loops", compiled._Loops),
           ("cw_layout", "inputs", compiled._Inputs), ("cw_layout", "clocks", compiled_clocks._Clocks),
           ("cw_layout", "rates", compiled._Rates),
           ("cw_layout", "fmi3", _Events),
           ("cw_layout", "fmi1", _Fmi1), ("cwme_layout", "me", _ME), ("cwme_layout", "sundials", cvode.Table),
           ("cwme_layout", "me_group", _Group)]
IDS = [name for _, name, _ in MIRRORS]


@pytest.fixture(scope="module")
def lib():
    core = compiled.load_core()
    assert core is not None, compiled.core_problem()
    return core


def _mirror(fields):
    return type("Mirror", (ctypes.Structure,), {"_fields_": fields})


@pytest.mark.parametrize("lookup, name, mirror", MIRRORS, ids=IDS)
def test_every_mirror_matches_the_core_field_by_field(lib, lookup, name, mirror):
    assert layout.problem(lib, lookup, name, mirror) is None


@pytest.mark.parametrize("lookup, name, mirror", MIRRORS, ids=IDS)
def test_any_two_fields_swapped_are_refused(lib, lookup, name, mirror):
    # Neighbours of one type keep every size: the check a size alone made passed them.
    fields = list(mirror._fields_)
    swaps = [k for k in range(len(fields) - 1) if fields[k][1] is fields[k + 1][1]]
    assert swaps
    for k in swaps:
        swapped = fields[:k] + [fields[k + 1], fields[k]] + fields[k + 2:]
        assert ctypes.sizeof(_mirror(swapped)) == ctypes.sizeof(mirror)
        said = layout.problem(lib, lookup, name, _mirror(swapped)) or ""
        assert fields[k][0] in said or fields[k + 1][0] in said


@pytest.mark.parametrize("lookup, name, mirror", MIRRORS, ids=IDS)
def test_a_field_renamed_added_or_dropped_is_refused(lib, lookup, name, mirror):
    fields = list(mirror._fields_)
    renamed = [(fields[0][0] + "_x", fields[0][1])] + fields[1:]
    assert "only in Python" in layout.problem(lib, lookup, name, _mirror(renamed))
    assert layout.problem(lib, lookup, name, _mirror(fields + [("extra", ctypes.c_int)])) is not None
    assert layout.problem(lib, lookup, name, _mirror(fields[:-1])) is not None


@pytest.mark.parametrize("lookup, name, mirror", MIRRORS, ids=IDS)
def test_a_field_the_c_table_leaves_out_is_found(lib, lookup, name, mirror, monkeypatch):
    # A field added to a C struct but to neither its table nor the mirror
    # leaves a gap in the table, wherever it is: mirrored structs have no
    # implicit padding (cw_layout.h).
    fields, size = layout._c_layout(lib, lookup, name)
    for left_out in fields:
        fewer = {n: f for n, f in fields.items() if n != left_out}
        assert layout._uncovered(fewer, size) is not None, left_out
    assert layout._uncovered(fields, size) is None


def test_an_unknown_struct_is_named(lib):
    assert "no layout for nothing" in layout.problem(lib, "cw_layout", "nothing", compiled._Port)


ROOT = Path(__file__).resolve().parents[1]


def _structs_in_header() -> set[str]:
    # cw_structs.h holds every struct Python mirrors, and only those.
    text = (ROOT / "src_c" / "master" / "cw_structs.h").read_text()
    return set(re.findall(r"^\}\s*cw_(\w+);", text, re.M))


def _mirrors_in_package() -> set[tuple[str, str]]:
    # Every ctypes Structure the package defines, by (module, class), found
    # in the source so that no module needs importing.
    found = set()
    for path in (ROOT / "clockwork").rglob("*.py"):
        tree = ast.parse(path.read_text(), str(path))
        module = ".".join(path.relative_to(ROOT).with_suffix("").parts)
        local = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.ClassDef):
                bases = {b.id if isinstance(b, ast.Name) else getattr(b, "attr", "") for b in node.bases}
                if bases & ({"Structure"} | local):
                    local.add(node.name)
                    found.add((module, node.name))
    return found


def test_every_struct_in_the_shared_header_is_mirrored_and_checked():
    assert _structs_in_header() == {name for _, name, _ in MIRRORS}


def test_every_ctypes_structure_in_the_package_is_checked():
    # Not mirrors: the layout table's own row, the base that makes
    # compiled's mirrors refuse unknown attributes, and the FMI 1.0 Model
    # Exchange structs an FMU reads (the standard's fmiCallbackFunctions
    # without Co-Simulation's stepFinished, and fmiEventInfo), which the
    # core never sees.
    not_mirrors = {("clockwork.fmi.layout", "_Field"), ("clockwork.engine.compiled", "_Strict"),
                   ("clockwork.fmi.me1", "CallbacksME1"), ("clockwork.fmi.me1", "EventInfo1")}
    checked = {(mirror.__module__, mirror.__qualname__) for _, _, mirror in MIRRORS}
    assert _mirrors_in_package() - not_mirrors == checked
