"""A small driver for one FMI 2.0 Co-Simulation instance, for tests and benchmarks.

It goes through fmpy.fmi2.FMU2Slave but calls the C functions directly
(`inst.raw.fmi2DoStep(...)`, fmpy has already set their ctypes signatures),
so that a refused call returns its status instead of raising, and so that
tight loops are not slowed by fmpy's status checks. Every message the FMU
logs is kept in `inst.messages`.

    with Instance(find_fmu("Pendulum"), params={"L": 0.5}) as p:
        p.step(0.01)
        p.get("phi")
"""

from __future__ import annotations

import atexit
import ctypes
import os
import shutil
from pathlib import Path
from typing import Iterable, NamedTuple

from fmpy import extract, read_model_description
from fmpy.fmi2 import (
    FMU2Slave,
    calloc,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
    fmi2CoSimulation,
    fmi2FMUstate,
    fmi2LastSuccessfulTime,
    free,
)

OK, WARNING, DISCARD, ERROR, FATAL = 0, 1, 2, 3, 4
STATUS_NAMES = {OK: "OK", WARNING: "Warning", DISCARD: "Discard", ERROR: "Error", FATAL: "Fatal"}

ROOT = Path(__file__).resolve().parents[2]


def guid_hash(data: bytes) -> int:
    """FNV-1a, byte by byte: the state header's hash of the model GUID."""
    h = 14695981039346656037
    for b in data:
        h = ((h ^ b) * 1099511628211) & 0xFFFFFFFFFFFFFFFF
    return h


def state_checksum(data: bytes) -> int:
    """The state's last 8 bytes (layout version 2): FNV-1a over
    little-endian 64-bit words, the tail byte by byte."""
    h = 14695981039346656037
    whole = len(data) - len(data) % 8
    for k in range(0, whole, 8):
        h = ((h ^ int.from_bytes(data[k:k + 8], "little")) * 1099511628211) & 0xFFFFFFFFFFFFFFFF
    for b in data[whole:]:
        h = ((h ^ b) * 1099511628211) & 0xFFFFFFFFFFFFFFFF
    return h


def find_fmu(name: str) -> Path:
    """<CW_FMU_DIR or fmus/>/<name>.fmu."""
    path = Path(os.environ.get("CW_FMU_DIR", ROOT / "fmus")) / f"{name}.fmu"
    if not path.exists():
        raise FileNotFoundError(f"{path} is missing: build the FMUs first")
    return path


_unpacked: dict[Path, tuple[object, str]] = {}


def unpack(fmu: Path | str):
    """(model description, unzip dir) of an FMU, extracted once per process."""
    key = Path(fmu).resolve()
    if key not in _unpacked:
        md = read_model_description(str(key))
        unzipdir = extract(str(key))
        atexit.register(shutil.rmtree, unzipdir, True)
        _unpacked[key] = (md, unzipdir)
    return _unpacked[key]


class Message(NamedTuple):
    status: int
    category: str
    text: str


class FmuError(RuntimeError):
    pass


class Logged:
    """What an FMI 2.0 and an FMI 3.0 instance share: the messages they
    logged (self.messages), the status check on them, and `with` calling
    free()."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.free()

    def log_text(self) -> str:
        return " | ".join(f"[{STATUS_NAMES.get(m.status, m.status)}] {m.text}" for m in self.messages)

    def errors(self) -> list[Message]:
        return [m for m in self.messages if m.status >= ERROR]

    def check(self, status: int, what: str) -> int:
        if status > WARNING:
            raise FmuError(f"{what} returned {STATUS_NAMES.get(status, status)}: {self.log_text()}")
        return status


class Instance(Logged):
    """One instance. `time` is the master's time: the next communication point."""

    def __init__(
        self,
        fmu: Path | str,
        params: dict | None = None,
        inputs: dict | None = None,
        *,
        name: str = "inst",
        start_time: float = 0.0,
        stop_time: float | None = None,
        logging_on: bool = False,
        guid: str | None = None,
        initialize: bool = True,
    ):
        self.md, self.unzipdir = unpack(fmu)
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.messages: list[Message] = []
        self.component = None

        def log(env, instance_name, status, category, message):
            self.messages.append(
                Message(status, (category or b"").decode(), (message or b"").decode())
            )

        cb = fmi2CallbackFunctions()
        cb.logger = fmi2CallbackLoggerTYPE(log)
        cb.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        cb.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self._callbacks = cb  # the C side keeps pointers to these
        self.slave = FMU2Slave(
            guid=self.md.guid,
            unzipDirectory=self.unzipdir,
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self.raw = self.slave.dll  # the fmi2 functions, with fmpy's argtypes
        resources = Path(self.unzipdir, "resources").as_uri()
        self.component = self.raw.fmi2Instantiate(
            name.encode(),
            fmi2CoSimulation,
            (guid if guid is not None else self.md.guid).encode(),
            resources.encode(),
            ctypes.byref(cb),
            0,
            1 if logging_on else 0,
        )
        if not self.component:
            self.component = None
            self.slave.freeLibrary()
            raise FmuError(f"fmi2Instantiate returned NULL: {self.log_text()}")
        self.c = ctypes.c_void_p(self.component)
        self.slave.component = self.component
        self.time = start_time
        if initialize:
            self.initialize(params, inputs, start_time=start_time, stop_time=stop_time)

    # -- lifetime ---------------------------------------------------------
    def free(self):
        if self.component is not None:
            self.raw.fmi2FreeInstance(self.c)
            self.component = None
            self.slave.freeLibrary()

    # -- initialization ---------------------------------------------------
    def setup(self, start_time=0.0, stop_time=None) -> int:
        self.time = start_time
        return self.raw.fmi2SetupExperiment(
            self.c, 0, 0.0, start_time, stop_time is not None,
            0.0 if stop_time is None else stop_time)

    def enter_init(self) -> int:
        return self.raw.fmi2EnterInitializationMode(self.c)

    def exit_init(self) -> int:
        return self.raw.fmi2ExitInitializationMode(self.c)

    def initialize(self, params=None, inputs=None, start_time=0.0, stop_time=None):
        self.check(self.setup(start_time, stop_time), "fmi2SetupExperiment")
        self.check(self.enter_init(), "fmi2EnterInitializationMode")
        for values in (params, inputs):
            if values:
                self.check(self.set(**values), "set")
        self.check(self.exit_init(), "fmi2ExitInitializationMode")
        return self

    # -- values -----------------------------------------------------------
    def vr(self, name: str) -> int:
        return self.vars[name].valueReference

    def set(self, **values) -> int:
        """Set variables by name, one call per type; returns the worst status."""
        worst = OK
        by_type: dict[str, list] = {}
        for name, value in values.items():
            typ = "Integer" if self.vars[name].type == "Enumeration" else self.vars[name].type
            by_type.setdefault(typ, []).append((self.vars[name].valueReference, value))
        for typ, items in by_type.items():
            n = len(items)
            vrs = (ctypes.c_uint * n)(*[vr for vr, _ in items])
            if typ == "Real":
                vals = (ctypes.c_double * n)(*[float(x) for _, x in items])
                st = self.raw.fmi2SetReal(self.c, vrs, n, vals)
            elif typ == "Integer":
                vals = (ctypes.c_int * n)(*[int(x) for _, x in items])
                st = self.raw.fmi2SetInteger(self.c, vrs, n, vals)
            elif typ == "Boolean":
                vals = (ctypes.c_int * n)(*[1 if x else 0 for _, x in items])
                st = self.raw.fmi2SetBoolean(self.c, vrs, n, vals)
            elif typ == "String":
                vals = (ctypes.c_char_p * n)(*[None if x is None else x.encode() for _, x in items])
                st = self.raw.fmi2SetString(self.c, vrs, n, vals)
            else:
                raise TypeError(f"cannot set {typ} variables")
            worst = max(worst, st)
            if st > WARNING:
                break
        return worst

    def get(self, name: str):
        return self.get_many([name])[0]

    def get_many(self, names: Iterable[str]) -> list:
        names = list(names)
        out = [None] * len(names)
        for typ in ("Real", "Integer", "Boolean", "String"):
            idx = [k for k, nm in enumerate(names)
                   if ("Integer" if self.vars[nm].type == "Enumeration" else self.vars[nm].type) == typ]
            if not idx:
                continue
            n = len(idx)
            vrs = (ctypes.c_uint * n)(*[self.vars[names[k]].valueReference for k in idx])
            if typ == "Real":
                vals = (ctypes.c_double * n)()
                st = self.raw.fmi2GetReal(self.c, vrs, n, vals)
            elif typ == "String":
                vals = (ctypes.c_char_p * n)()
                st = self.raw.fmi2GetString(self.c, vrs, n, vals)
            else:
                vals = (ctypes.c_int * n)()
                fn = self.raw.fmi2GetInteger if typ == "Integer" else self.raw.fmi2GetBoolean
                st = fn(self.c, vrs, n, vals)
            self.check(st, f"fmi2Get{typ}")
            for j, k in enumerate(idx):
                out[k] = bool(vals[j]) if typ == "Boolean" else vals[j].decode() if typ == "String" else vals[j]
        return out

    def set_input_derivatives(self, values: dict[str, dict[int, float]]) -> int:
        """values = {"tau": {1: du/dt, 2: d2u/dt2}}"""
        items = [(self.vr(nm), order, float(x)) for nm, d in values.items() for order, x in d.items()]
        n = len(items)
        vrs = (ctypes.c_uint * n)(*[i[0] for i in items])
        orders = (ctypes.c_int * n)(*[i[1] for i in items])
        vals = (ctypes.c_double * n)(*[i[2] for i in items])
        return self.raw.fmi2SetRealInputDerivatives(self.c, vrs, n, orders, vals)

    def output_derivative(self, name: str, order: int) -> tuple[int, float]:
        vrs = (ctypes.c_uint * 1)(self.vr(name))
        orders = (ctypes.c_int * 1)(order)
        val = (ctypes.c_double * 1)()
        st = self.raw.fmi2GetRealOutputDerivatives(self.c, vrs, 1, orders, val)
        return st, val[0]

    # -- stepping ---------------------------------------------------------
    def step(self, h: float, tc: float | None = None) -> int:
        """fmi2DoStep from tc (default: the master's time); advances `time` on OK."""
        t = self.time if tc is None else tc
        st = self.raw.fmi2DoStep(self.c, t, h, 1)
        if st <= WARNING:
            self.time = t + h
        return st

    def advance(self, h: float, n: int = 1):
        for _ in range(n):
            self.check(self.step(h), f"fmi2DoStep at t = {self.time!r}")
        return self

    def last_successful_time(self) -> float:
        v = ctypes.c_double()
        self.check(self.raw.fmi2GetRealStatus(self.c, fmi2LastSuccessfulTime, ctypes.byref(v)),
                   "fmi2GetRealStatus")
        return v.value

    # -- FMU state --------------------------------------------------------
    def get_state(self, state: fmi2FMUstate | None = None) -> fmi2FMUstate:
        state = fmi2FMUstate() if state is None else state
        self.check(self.raw.fmi2GetFMUstate(self.c, ctypes.byref(state)), "fmi2GetFMUstate")
        return state

    def set_state(self, state: fmi2FMUstate) -> int:
        return self.raw.fmi2SetFMUstate(self.c, state)

    def free_state(self, state: fmi2FMUstate) -> int:
        return self.raw.fmi2FreeFMUstate(self.c, ctypes.byref(state))

    def serialize(self, state: fmi2FMUstate) -> bytes:
        size = ctypes.c_size_t()
        self.check(self.raw.fmi2SerializedFMUstateSize(self.c, state, ctypes.byref(size)),
                   "fmi2SerializedFMUstateSize")
        buf = ctypes.create_string_buffer(size.value)
        self.check(self.raw.fmi2SerializeFMUstate(self.c, state, buf, size.value),
                   "fmi2SerializeFMUstate")
        return buf.raw

    def deserialize(self, data: bytes) -> tuple[int, fmi2FMUstate]:
        """(status, state); the state is NULL unless the status is OK."""
        buf = ctypes.create_string_buffer(data, len(data))
        state = fmi2FMUstate()
        st = self.raw.fmi2DeSerializeFMUstate(self.c, buf, len(data), ctypes.byref(state))
        return st, state
