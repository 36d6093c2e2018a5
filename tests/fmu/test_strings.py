"""String variables in the runtime (TestTypes: p_str, u_str, y_str = p_str
u_str): fmi2Get/SetString, the instance's own copies, reset, and the String
section of the FMU state (docs/design.md "FMU state layout"); and the
runtime faults that fuzzing TestTypes found (docs/reliability.md)."""

from __future__ import annotations

import ctypes
import struct

import pytest

from cwtest import fmu_file, test_fmu
from fmu_driver import ERROR, OK, Instance, state_checksum


@pytest.fixture(scope="module")
def types():
    return test_fmu("TestTypes")


def test_strings_are_set_copied_and_read(types):
    with Instance(types, params={"p_str": "ab"}) as p:
        assert p.get_many(["p_str", "u_str", "y_str"]) == ["ab", "", "ab"]
        given = ctypes.create_string_buffer(b"cd")
        vr = (ctypes.c_uint * 1)(p.vr("u_str"))
        assert p.raw.fmi2SetString(p.c, vr, 1, (ctypes.c_char_p * 1)(ctypes.addressof(given))) == OK
        given.value = b"XX"  # the instance holds its own copy
        assert p.get_many(["u_str", "y_str"]) == ["cd", "abcd"]
        assert p.set(u_str="é, \"quoted\"") == OK
        assert p.get("y_str") == "abé, \"quoted\""
        assert p.step(0.1) == OK and p.get("y_str") == "abé, \"quoted\""


@pytest.mark.parametrize("values, needle", [
    (dict(u_str=None), "the value of u_str is NULL"),
    (dict(y_str="x"), "cannot set 'y_str'"),
])
def test_a_bad_string_set_is_refused_with_a_message(types, values, needle):
    with Instance(types) as p:
        assert p.set(**values) == ERROR
        assert needle in p.log_text()


def test_a_string_read_of_another_type_is_refused(types):
    with Instance(types) as p:
        vrs = (ctypes.c_uint * 1)(p.vr("y_int"))
        out = (ctypes.c_char_p * 1)()
        assert p.raw.fmi2GetString(p.c, vrs, 1, out) == ERROR
        assert "not the value reference of a String variable" in p.log_text()


def test_reset_gives_back_the_start_strings(types):
    with Instance(types, params={"p_str": "head"}, inputs={"u_str": "tail"}) as p:
        assert p.get("y_str") == "headtail"
        assert p.raw.fmi2Reset(p.c) == OK
        p.initialize()
        assert p.get_many(["p_str", "u_str", "y_str"]) == ["tick", "", "tick"]


def test_the_state_holds_the_strings_and_round_trips(types):
    with Instance(types, params={"p_str": "p"}, inputs={"u_str": "first"}) as p:
        p.advance(0.1)
        saved = p.get_state()
        data = p.serialize(saved)
        # The section after the counters: u32 byte count and bytes, per String in table order.
        assert data[-8 - (4 + 1 + 4 + 5 + 4 + 6):-8] == (
            struct.pack("<I", 1) + b"p" + struct.pack("<I", 5) + b"first" + struct.pack("<I", 6) + b"pfirst")
        assert p.set(u_str="second, longer") == OK
        p.advance(0.1)
        assert p.get("y_str") == "psecond, longer"
        assert p.set_state(saved) == OK
        assert p.get_many(["u_str", "y_str"]) == ["first", "pfirst"]
        # Serialized and read back into a fresh instance: the same strings.
        with Instance(types) as q:
            st, s2 = q.deserialize(data)
            assert st == OK and q.set_state(s2) == OK
            assert q.get_many(["p_str", "u_str", "y_str"]) == ["p", "first", "pfirst"]
            assert q.serialize(q.get_state()) == data
        p.free_state(saved)


def _rechecksummed(data: bytes) -> bytes:
    return data[:-8] + state_checksum(data[:-8]).to_bytes(8, "little")


# The String section of TestTypes' state ends with y_str: count at [-18:-14], bytes at [-14:-8].
@pytest.mark.parametrize("damage, fix_header, needle", [
    (lambda d: d[:-9] + d[-8:], False, "the state header says"),
    (lambda d: d[:-9] + d[-8:], True, "is not 6 bytes of text"),  # ends inside y_str
    (lambda d: d[:-14] + b"\x00" + d[-13:], True, "is not 6 bytes of text"),  # a NUL inside
    (lambda d: d[:-18] + struct.pack("<I", 99) + d[-14:], True, "is not 99 bytes of text"),
    (lambda d: d[:-8] + b"more" + d[-8:], True, "4 bytes after its Strings"),
])
def test_a_damaged_string_section_is_refused_and_changes_nothing(types, damage, fix_header, needle):
    with Instance(types, params={"p_str": "p"}, inputs={"u_str": "first"}) as p:
        bad = bytearray(damage(p.serialize(p.get_state())))
        if fix_header:
            struct.pack_into("<I", bad, 16, len(bad))
        st, _ = p.deserialize(_rechecksummed(bytes(bad)))
        assert st == ERROR and needle in p.log_text(), p.log_text()
        assert p.get_many(["u_str", "y_str"]) == ["first", "pfirst"]


def test_a_model_without_strings_keeps_its_state_layout():
    # Pendulum has no String: the state is the fixed layout, byte count from docs/design.md.
    with Instance(fmu_file("Pendulum")) as p:
        data = p.serialize(p.get_state())
        md = p.md
        values = sum(32 if v.type == "Real" and v.causality == "input" else 8 if v.type == "Real" else 4
                     for v in md.modelVariables)
        n_real, = struct.unpack_from("<I", data, 32 + values)
        n_uint, = struct.unpack_from("<I", data, 32 + values + 4 + 8 * n_real)
        assert len(data) == 32 + values + 4 + 8 * n_real + 4 + 8 * n_uint + 8
        assert struct.unpack_from("<I", data, 16)[0] == len(data)


def _rss_bytes() -> int:
    import os

    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def test_replaced_strings_are_freed(types):
    """Every set, output refresh and state restore replaces copies: 20000
    rounds of 1 kB strings would leak ~60 MB if the old ones were kept."""
    text = "x" * 1000
    with Instance(types, params={"p_str": text}) as p:
        saved = p.get_state()

        def rounds(n):
            for k in range(n):
                assert p.set(u_str=text) == OK
                assert p.get("y_str") == text + text
                assert p.get_state(saved) and p.set_state(saved) == OK

        rounds(1000)
        before = _rss_bytes()
        rounds(20_000)
        grown = _rss_bytes() - before
        p.free_state(saved)
    assert grown < 1 << 20, grown


def test_a_state_with_a_boolean_other_than_0_or_1_is_refused(types):
    # Found by fuzz/fuzz_fmu.c on TestTypes: the range check let any integer through.
    with Instance(types) as p:
        data = bytearray(p.serialize(p.get_state()))
        off = 32
        for v in sorted(p.md.modelVariables, key=lambda v: v.valueReference):
            if v.name == "u_bool":
                break
            if v.type != "String":
                off += (32 if v.causality == "input" else 8) if v.type == "Real" else 4
        assert struct.unpack_from("<i", data, off)[0] == 0
        struct.pack_into("<i", data, off, 7)
        st, _ = p.deserialize(_rechecksummed(bytes(data)))
        assert st == ERROR and "u_bool = 7 is not a Boolean" in p.log_text(), p.log_text()


def test_an_output_showing_an_input_slope_follows_fmi2SetRealInputDerivatives(types):
    # Found by fuzz/fuzz_fmu.c on TestTypes: u_rate kept the slope it was computed with.
    with Instance(types) as p:
        assert p.get("u_rate") == 0.0
        assert p.set_input_derivatives({"u_real": {1: 2.5}}) == OK
        assert p.get("u_rate") == 2.5
