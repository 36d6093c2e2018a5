"""How a Model Exchange face hands the compiled core its FMU's get and set
of a discrete type, for the connections inside a Model Exchange group
(engine/me_group.py, src_c/master/cw_me_group.c): the functions' addresses
and the shape of a value in their calls (cw_structs.h's CW_VALUE_*), so
that the core calls them without asking the FMU's version."""

from __future__ import annotations

import ctypes
from ctypes import c_void_p

VALUE_COUNTED = 16  # the call takes the number of values after them
VALUE_BOOLEAN = 32  # a Boolean: any non-zero value is true


def value_calls(get, set_, size_bytes: int, counted: bool, boolean: bool) -> tuple[int, int, int]:
    """(the get's address, the set's address, the value's shape)."""
    shape = size_bytes | (VALUE_COUNTED if counted else 0) | (VALUE_BOOLEAN if boolean else 0)
    return ctypes.cast(get, c_void_p).value, ctypes.cast(set_, c_void_p).value, shape
