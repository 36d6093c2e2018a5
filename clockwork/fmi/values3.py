"""Values of every FMI 3.0 type, for a face that has an FMI 3.0 instance
(the Co-Simulation face ``cs3.Instance3`` and the Model Exchange face
``me3.ModelExchange3``): each type through its own fmi3Get*/fmi3Set*,
arrays whole, integers refused where their type cannot hold them. Not on
the hot path.
"""

from __future__ import annotations

import ctypes
import weakref
from ctypes import (POINTER, c_bool, c_char_p, c_double, c_float, c_int, c_int8, c_int16, c_int32, c_int64,
                    c_size_t, c_uint, c_uint8, c_uint16, c_uint32, c_uint64, c_void_p)

from ..errors import SceneError, SimulationError
from .description import array_elements, int_range, type_name

# The C type of each FMI 3.0 number type (an Enumeration goes through fmi3Get/SetInt64).
_CTYPES = {"Float32": c_float, "Float64": c_double, "Int8": c_int8, "UInt8": c_uint8, "Int16": c_int16,
           "UInt16": c_uint16, "Int32": c_int32, "UInt32": c_uint32, "Int64": c_int64, "UInt64": c_uint64,
           "Boolean": c_bool, "String": c_char_p, "Enumeration": c_int64}


class Values3:
    """The values of an FMI 3.0 instance `owner` (an instance of the
    contract: its variables, model description, arrays, component,
    ``check`` and ``c_setReal``, through which Float64 values go so that
    whatever the owner keeps of its real inputs stays true), through the
    functions of the library `dll`."""

    def __init__(self, owner, dll):
        self.owner = weakref.proxy(owner)  # no cycle: the owner is freed when it goes
        self.dll = dll
        self._fns: dict = {}  # kind -> (fmi3Get<kind>, fmi3Set<kind>), bound once per type

    def _value_functions(self, kind: str):
        """(fmi3Get<kind>, fmi3Set<kind>), bound once per type."""
        fns = self._fns
        if kind not in fns:
            name = "Int64" if kind == "Enumeration" else kind
            vrs = POINTER(c_uint)
            if kind == "Binary":
                args = [c_void_p, vrs, c_size_t, POINTER(c_size_t), POINTER(POINTER(c_uint8)), c_size_t]
            else:
                args = [c_void_p, vrs, c_size_t, POINTER(_CTYPES[kind]), c_size_t]
            pair = []
            for prefix in ("fmi3Get", "fmi3Set"):
                f = getattr(self.dll, prefix + name)
                f.argtypes, f.restype = args, c_int
                pair.append(f)
            fns[kind] = tuple(pair)
        return fns[kind]

    def _get_array(self, name: str) -> list:
        """Every value of an array variable (row-major), through the fmi3Get* of its type."""
        o = self.owner
        v = o.variables[name]
        kind = type_name(o.md, v)
        vr, size = o.arrays[name]
        out = (_CTYPES[kind] * max(1, size))()
        o.check(self._value_functions(kind)[0](o.component, (c_uint * 1)(vr), 1, out, size),
                f"fmi3Get{kind} ({name})")
        return [(x or b"").decode("utf-8", "replace") if kind == "String" else x for x in out[:size]]

    def get_values(self, names: list[str]) -> list:
        """Values of any type, each through the fmi3Get* of its type: numbers
        as Python numbers, Boolean as bool, String as text, Binary as
        hexadecimal digits; an array element's value, an array's values as a
        list (row-major)."""
        o = self.owner
        values = []
        arrays: dict[str, list] = {}  # each array read once per call
        for n in names:
            v = o.variables[n]
            if v.shape or v.array is not None:
                name = n if v.shape else v.array
                if name not in arrays:
                    arrays[name] = self._get_array(name)
                values.append(list(arrays[name]) if v.shape else arrays[name][v.index])
                continue
            kind = type_name(o.md, v)
            get = self._value_functions(kind)[0]
            vr = (c_uint * 1)(v.vr)
            if kind == "Binary":
                size, data = (c_size_t * 1)(), (POINTER(c_uint8) * 1)()
                o.check(get(o.component, vr, 1, size, data, 1), f"fmi3GetBinary ({n})")
                values.append(ctypes.string_at(data[0], size[0]).hex() if size[0] else "")
                continue
            out = (_CTYPES[kind] * 1)()
            o.check(get(o.component, vr, 1, out, 1), f"fmi3Get{kind} ({n})")
            x = out[0]
            values.append((x or b"").decode("utf-8", "replace") if kind == "String" else x)
        return values

    def set_values(self, values: dict[str, object], what: str = "fmi3Set*",
                   error: type[SimulationError] = SimulationError) -> None:
        """Set variables of any type through the fmi3Set* of its type (Binary
        from hexadecimal digits); a value an integer type cannot hold is
        refused here, never wrapped. An array takes a list of all its values
        (nested by its shape or flat, row-major) or values of single elements
        (``A[1,2]``), which the array's other values join: the array's own
        value given beside them, else its start values."""
        o = self.owner
        values = self._merge_elements(values)
        for n, value in values.items():
            v = o.variables[n]
            if v.causality == "structuralParameter":
                raise error(f"{what}: {o.name}.{n} is a structural parameter (an array size): clockwork does "
                            "not change structural parameters (FMI 3.0 configuration mode)", instance=o.name)
            kind = type_name(o.md, v)
            if v.shape:
                self._set_array(n, kind, value, what, error)
                continue
            vr = (c_uint * 1)(v.vr)
            if kind == "Float64":  # through c_setReal, which the intermediate update may keep
                st = o.c_setReal(o.component, vr, 1, (c_double * 1)(float(value)))
            elif kind == "Binary":
                data = bytes.fromhex(str(value))
                buf = (c_uint8 * max(1, len(data)))(*data)
                st = self._value_functions(kind)[1](o.component, vr, 1, (c_size_t * 1)(len(data)),
                         (POINTER(c_uint8) * 1)(ctypes.cast(buf, POINTER(c_uint8))), 1)
            else:
                if kind == "String":
                    x = str(value).encode("utf-8")
                elif kind == "Boolean":
                    x = bool(value)
                elif kind in ("Float32", "Float64"):
                    x = float(value)
                else:
                    x = int(value)
                    bounds = int_range(kind)
                    if bounds and not bounds[0] <= x <= bounds[1]:
                        raise error(f"{what}: {o.name}.{n} = {x} is out of the range of {kind} "
                                    f"[{bounds[0]}, {bounds[1]}]")
                st = self._value_functions(kind)[1](o.component, vr, 1, (_CTYPES[kind] * 1)(x), 1)
            o.check(st, f"{what} ({n} = {value!r})", error=error)

    def _merge_elements(self, values: dict[str, object]) -> dict[str, object]:
        """`values` with the elements of each array gathered into the array's
        list of values (FMI 3.0 sets an array whole); an element's value wins
        over the array's own."""
        o = self.owner
        if not o.arrays or all(o.variables[n].array is None for n in values):
            return values
        out: dict[str, object] = {}
        elements: dict[str, list] = {}
        for n, value in values.items():
            v = o.variables[n]
            if v.array is None:
                out[n] = value
            else:
                elements.setdefault(v.array, []).append((v.index, value))
        for name, pairs in elements.items():
            size = o.arrays[name][1]
            if name in values:
                merged = list(flat_values(values[name]))
            elif len({k for k, _ in pairs}) == size:  # every element given
                merged = [None] * size
            else:
                merged = self._start_values(name)
            if len(merged) == size:  # else _set_array says what is wrong
                for k, x in pairs:
                    merged[k] = x
            out[name] = merged
        return out

    def _start_values(self, name: str) -> list:
        """An array's start values (row-major), from its modelDescription.xml."""
        o = self.owner
        v = next(x for x in o.md.modelVariables if x.name == name)
        starts = [e.start for e in array_elements(v)]
        if any(x is None for x in starts):
            raise SceneError(f"{o.name}.{name}: the array has no start value for every element, so one "
                             f"element cannot be set alone: set the whole array")
        kind = type_name(o.md, o.variables[name])
        if kind in ("Float32", "Float64"):
            return [float(x) for x in starts]
        if kind == "Boolean":
            return [str(x).strip().lower() in ("true", "1") for x in starts]
        if kind == "String":
            return list(starts)
        return [int(x) for x in starts]

    def _set_array(self, name: str, kind: str, value, what: str, error: type[SimulationError]) -> None:
        """Set every value of an array variable through the fmi3Set* of its type."""
        o = self.owner
        vr, size = o.arrays[name]
        flat = list(flat_values(value))
        if len(flat) != size:
            raise error(f"{what}: {o.name}.{name} is an array of {size} values, given {len(flat)}",
                        instance=o.name)
        if kind == "String":
            flat = [str(x).encode("utf-8") for x in flat]
        elif kind == "Boolean":
            flat = [bool(x) for x in flat]
        elif kind in ("Float32", "Float64"):
            flat = [float(x) for x in flat]
        else:
            flat = [int(x) for x in flat]
            bounds = int_range(kind)
            bad = next((x for x in flat if bounds and not bounds[0] <= x <= bounds[1]), None)
            if bad is not None:
                raise error(f"{what}: {o.name}.{name} holds {bad}, out of the range of {kind} "
                            f"[{bounds[0]}, {bounds[1]}]")
        st = self._value_functions(kind)[1](o.component, (c_uint * 1)(vr), 1,
                                            (_CTYPES[kind] * max(1, size))(*flat), size)
        o.check(st, f"{what} ({name}, {size} values)", error=error)


def flat_values(value):
    """The values of a nested list (or tuple), row-major; a scalar as itself."""
    if isinstance(value, (list, tuple)):
        for x in value:
            yield from flat_values(x)
    else:
        yield value
