"""A small driver for one FMI 3.0 Co-Simulation instance, for tests: the FMI
3.0 twin of fmu_driver.py.

It goes through fmpy.fmi3.FMU3Slave for loading and the ctypes signatures,
but calls the C functions directly (`inst.raw.fmi3DoStep(...)`), so that a
refused call returns its status instead of raising. Every message the FMU
logs is kept in `inst.messages`.

    with Instance3(find_fmu3("Pendulum"), params={"L": 0.5}, early_return=True) as p:
        r = p.step(0.5)      # (status, eventHandlingNeeded, terminate, earlyReturn, lastSuccessfulTime)
        p.get("phi")
"""

from __future__ import annotations

import ctypes
import os
from pathlib import Path
from typing import Iterable, NamedTuple

from fmpy.fmi3 import FMU3Slave, fmi3FMUState, fmi3IntermediateUpdateCallback, fmi3LogMessageCallback

from fmu_driver import OK, ROOT, WARNING, FmuError, Logged, Message, unpack

CTYPES = {"Float64": ctypes.c_double, "Int32": ctypes.c_int32, "Boolean": ctypes.c_bool}


def find_fmu3(name: str) -> Path:
    """<CW_FMU_DIR or fmus/>/fmi3/<name>.fmu: the FMI 3.0 build."""
    path = Path(os.environ.get("CW_FMU_DIR", ROOT / "fmus")) / "fmi3" / f"{name}.fmu"
    if not path.exists():
        raise FileNotFoundError(f"{path} is missing: build the FMUs first")
    return path


class StepResult(NamedTuple):
    status: int
    event_handling_needed: bool
    terminate: bool
    early_return: bool
    last_successful_time: float


class Instance3(Logged):
    """One FMI 3.0 instance. `time` is the importer's time: the next communication point."""

    def __init__(self, fmu, params: dict | None = None, inputs: dict | None = None, *,
                 name: str = "inst", start_time: float = 0.0, stop_time: float | None = None,
                 event_mode: bool = False, early_return: bool = False, logging_on: bool = False,
                 token: str | None = None, initialize: bool = True, intermediate_update=None):
        self.md, self.unzipdir = unpack(fmu)
        self.vars = {v.name: v for v in self.md.modelVariables}
        self.messages: list[Message] = []
        self.instance = None

        def log(env, status, category, message):
            self.messages.append(Message(status, (category or b"").decode(), (message or b"").decode()))

        self._log = fmi3LogMessageCallback(log)  # the C side keeps the pointer
        # intermediate_update(inst, time, set_requested, get_allowed, step_finished, can_return_early)
        self._intermediate = fmi3IntermediateUpdateCallback(
            (lambda env, t, set_req, get_ok, finished, can_return, early_req, early_time:
             intermediate_update(self, t, set_req, get_ok, finished, can_return))
            if intermediate_update else 0)
        self.slave = FMU3Slave(guid=self.md.guid, unzipDirectory=self.unzipdir,
                               modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=name)
        self.raw = self.slave.dll  # the fmi3 functions, with fmpy's argtypes
        self.instance = self.raw.fmi3InstantiateCoSimulation(
            name.encode(), (token if token is not None else self.md.instantiationToken).encode(),
            str(Path(self.unzipdir, "resources")).encode(), False, logging_on, event_mode,
            early_return, None, 0, None, self._log, self._intermediate)
        if not self.instance:
            self.instance = None
            self.slave.freeLibrary()
            raise FmuError(f"fmi3InstantiateCoSimulation returned NULL: {self.log_text()}")
        self.c = ctypes.c_void_p(self.instance)
        self.time = start_time
        self.event_mode = event_mode
        if initialize:
            self.initialize(params, inputs, start_time=start_time, stop_time=stop_time)

    # -- lifetime ---------------------------------------------------------
    def free(self):
        if self.instance is not None:
            self.raw.fmi3FreeInstance(self.c)
            self.instance = None
            self.slave.freeLibrary()

    # -- modes ------------------------------------------------------------
    def enter_init(self, start_time=0.0, stop_time=None) -> int:
        st = self.raw.fmi3EnterInitializationMode(self.c, False, 0.0, start_time, stop_time is not None,
                                                  0.0 if stop_time is None else stop_time)
        if st <= WARNING:
            self.time = start_time
        return st

    def exit_init(self) -> int:
        return self.raw.fmi3ExitInitializationMode(self.c)

    def update_discrete_states(self) -> tuple[int, list[bool]]:
        flags = [ctypes.c_bool() for _ in range(5)]
        t_next = ctypes.c_double()
        st = self.raw.fmi3UpdateDiscreteStates(self.c, *[ctypes.byref(f) for f in flags], ctypes.byref(t_next))
        return st, [f.value for f in flags]

    def settle(self) -> None:
        """In Event Mode: update the discrete states until stable, then Step Mode."""
        while True:
            st, flags = self.update_discrete_states()
            self.check(st, "fmi3UpdateDiscreteStates")
            if not flags[0]:
                break
        self.check(self.raw.fmi3EnterStepMode(self.c), "fmi3EnterStepMode")

    def initialize(self, params=None, inputs=None, start_time=0.0, stop_time=None):
        self.check(self.enter_init(start_time, stop_time), "fmi3EnterInitializationMode")
        for values in (params, inputs):
            if values:
                self.check(self.set(**values), "set")
        self.check(self.exit_init(), "fmi3ExitInitializationMode")
        if self.event_mode:
            self.settle()
        return self

    # -- values -----------------------------------------------------------
    def vr(self, name: str) -> int:
        return self.vars[name].valueReference

    def set(self, **values) -> int:
        worst = OK
        by_type: dict[str, list] = {}
        for name, value in values.items():
            by_type.setdefault(self.vars[name].type, []).append((self.vr(name), value))
        for typ, items in by_type.items():
            n = len(items)
            vrs = (ctypes.c_uint32 * n)(*[vr for vr, _ in items])
            vals = (CTYPES[typ] * n)(*[x for _, x in items])
            st = getattr(self.raw, f"fmi3Set{typ}")(self.c, vrs, n, vals, n)
            worst = max(worst, st)
            if st > WARNING:
                break
        return worst

    def get(self, name: str):
        return self.get_many([name])[0]

    def get_many(self, names: Iterable[str]) -> list:
        names = list(names)
        out = [None] * len(names)
        for typ in CTYPES:
            idx = [k for k, nm in enumerate(names) if self.vars[nm].type == typ]
            if not idx:
                continue
            n = len(idx)
            vrs = (ctypes.c_uint32 * n)(*[self.vr(names[k]) for k in idx])
            vals = (CTYPES[typ] * n)()
            self.check(getattr(self.raw, f"fmi3Get{typ}")(self.c, vrs, n, vals, n), f"fmi3Get{typ}")
            for j, k in enumerate(idx):
                out[k] = vals[j]
        return out

    # -- stepping ---------------------------------------------------------
    def step(self, h: float, tc: float | None = None) -> StepResult:
        """fmi3DoStep from tc (default: the importer's time); `time` becomes
        lastSuccessfulTime on OK."""
        t = self.time if tc is None else tc
        flags = [ctypes.c_bool() for _ in range(3)]
        last = ctypes.c_double()
        st = self.raw.fmi3DoStep(self.c, t, h, True, *[ctypes.byref(f) for f in flags], ctypes.byref(last))
        if st <= WARNING:
            self.time = last.value
        return StepResult(st, flags[0].value, flags[1].value, flags[2].value, last.value)

    # -- FMU state --------------------------------------------------------
    def get_state(self, state: fmi3FMUState | None = None) -> fmi3FMUState:
        state = fmi3FMUState() if state is None else state
        self.check(self.raw.fmi3GetFMUState(self.c, ctypes.byref(state)), "fmi3GetFMUState")
        return state

    def set_state(self, state) -> int:
        return self.raw.fmi3SetFMUState(self.c, state)

    def free_state(self, state) -> int:
        return self.raw.fmi3FreeFMUState(self.c, ctypes.byref(state))

    def serialize(self, state) -> bytes:
        size = ctypes.c_size_t()
        self.check(self.raw.fmi3SerializedFMUStateSize(self.c, state, ctypes.byref(size)),
                   "fmi3SerializedFMUStateSize")
        buf = (ctypes.c_uint8 * size.value)()
        self.check(self.raw.fmi3SerializeFMUState(self.c, state, buf, size.value), "fmi3SerializeFMUState")
        return bytes(buf)

    def deserialize(self, data: bytes) -> tuple[int, fmi3FMUState]:
        buf = (ctypes.c_uint8 * len(data)).from_buffer_copy(data)
        state = fmi3FMUState()
        st = self.raw.fmi3DeserializeFMUState(self.c, buf, len(data), ctypes.byref(state))
        return st, state
