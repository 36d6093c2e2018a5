"""The ctypes mirrors of the compiled core's structs, checked field by field.

The core exports each mirrored struct's layout (src_c/master/cw_layout.h):
every field's name, offset, size and alignment, and the struct's size.
``problem`` compares a ctypes Structure with it: the same field names, each
at the same offset with the same size, and the C table covering its struct
(no gap, ending where sizeof says: mirrored structs pad explicitly). A size check
alone passes two swapped fields of one type, or a field added in C where
the padding had room.
"""

from __future__ import annotations

import ctypes
from ctypes import POINTER, Structure, c_char_p, c_size_t, c_void_p


class _Field(Structure):
    _fields_ = [("name", c_char_p), ("offset", c_size_t), ("size", c_size_t), ("align", c_size_t)]


def _c_layout(lib, lookup: str, name: str) -> tuple[dict[str, tuple[int, int, int]], int] | None:
    fn = getattr(lib, lookup, None)
    if fn is None:
        return None
    fn.argtypes = [c_char_p, POINTER(c_size_t), POINTER(c_size_t)]
    fn.restype = c_void_p
    n, size = c_size_t(), c_size_t()
    address = fn(name.encode(), ctypes.byref(n), ctypes.byref(size))
    if not address:
        return None
    table = (_Field * n.value).from_address(address)
    return {f.name.decode(): (f.offset, f.size, f.align) for f in table}, size.value


def _uncovered(fields: dict[str, tuple[int, int, int]], size: int) -> str | None:
    """Where the table leaves a gap, or None. Mirrored structs have no
    implicit padding (cw_layout.h), so any gap is a field it does not list."""
    end = 0
    for name, (offset, width, _align) in sorted(fields.items(), key=lambda item: item[1][0]):
        if offset != end:
            return f"bytes {end}-{offset} before {name} are no field the table lists"
        end = offset + width
    if end != size:
        return f"bytes {end}-{size} at the end are no field the table lists"
    return None


def problem(lib, lookup: str, name: str, mirror: type[Structure]) -> str | None:
    """Why the ctypes `mirror` does not match the core's struct `name`, or None."""
    found = _c_layout(lib, lookup, name)
    if found is None:
        return f"the core has no layout for {name}"
    fields, size = found
    gap = _uncovered(fields, size)
    if gap:
        return f"{name}: {gap}"
    mine = {n: (getattr(mirror, n).offset, getattr(mirror, n).size) for n, _ in mirror._fields_}
    if set(mine) != set(fields):
        missing, extra = sorted(set(fields) - set(mine)), sorted(set(mine) - set(fields))
        return f"{name}: fields only in C {missing}, only in Python {extra}"
    for n, (offset, width) in mine.items():
        if (offset, width) != fields[n][:2]:
            return (f"{name}.{n}: offset {offset}, size {width} in Python, "
                    f"offset {fields[n][0]}, size {fields[n][1]} in C")
    if ctypes.sizeof(mirror) != size:
        return f"{name}: {ctypes.sizeof(mirror)} bytes in Python, {size} in C"
    return None
