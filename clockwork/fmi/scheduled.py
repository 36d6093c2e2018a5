"""The calls of FMI 3.0 clocks and Scheduled Execution on one instance.

``ClockCalls`` binds the fmi3 functions of clocks, of Event Mode and of
Scheduled Execution on one instance (engine/clocks.py drives them).
``ScheduledInstance`` is an FMI 3.0 Scheduled Execution FMU behind the
master's calls: it has no step of its own (its ``c_doStep`` moves
nothing); its partitions run when the engine activates their clocks.
"""

from __future__ import annotations

import ctypes
import math
from ctypes import CFUNCTYPE, POINTER, byref, c_bool, c_char_p, c_double, c_int, c_size_t, c_uint, c_void_p, cast

from ..errors import SceneError, SimulationError
from .archive import extract
from .calls import OK, WARNING, declared, new_slave, read_string
from .clocks import Clock
from .contract import CORE_CALLS
from .cs3 import LOG_MESSAGE, Instance3


class ClockCalls:
    """The fmi3 functions of clocks and Event Mode on one instance."""

    def __init__(self, inst: Instance3):
        self.inst = inst
        dll = inst._slave.dll
        vrs, pb = POINTER(c_uint), POINTER(c_bool)

        def fn(name, *args):
            return declared(dll, name, args)

        self._get_clock = fn("fmi3GetClock", c_void_p, vrs, c_size_t, pb)
        self._set_clock = fn("fmi3SetClock", c_void_p, vrs, c_size_t, pb)
        self._interval = fn("fmi3GetIntervalDecimal", c_void_p, vrs, c_size_t, POINTER(c_double), POINTER(c_int))
        self._shift = fn("fmi3GetShiftDecimal", c_void_p, vrs, c_size_t, POINTER(c_double))
        self._activate = fn("fmi3ActivateModelPartition", c_void_p, c_uint, c_double)
        self._enter_event = fn("fmi3EnterEventMode", c_void_p)
        self._update = fn("fmi3UpdateDiscreteStates", c_void_p, pb, pb, pb, pb, pb, POINTER(c_double))
        self._enter_step = fn("fmi3EnterStepMode", c_void_p)

    def _check(self, st: int, what: str, t: float) -> None:
        if st > WARNING:
            raise self.inst.fail(what, st, t)

    def enter_event_mode(self, t: float) -> None:
        self._check(self._enter_event(self.inst.component), "fmi3EnterEventMode", t)

    def set_clocks(self, clocks: list[Clock], t: float) -> None:
        n = len(clocks)
        self._check(self._set_clock(self.inst.component, (c_uint * n)(*(c.vr for c in clocks)), n,
                                    (c_bool * n)(*([True] * n))),
                    f"fmi3SetClock ({', '.join(c.name for c in clocks)})", t)

    def get_clocks(self, clocks: list[Clock], t: float) -> list[bool]:
        n = len(clocks)
        out = (c_bool * max(1, n))()
        if n:
            self._check(self._get_clock(self.inst.component, (c_uint * n)(*(c.vr for c in clocks)), n, out),
                        f"fmi3GetClock ({', '.join(c.name for c in clocks)})", t)
        return [bool(x) for x in out[:n]]

    def interval(self, clock: Clock, t: float) -> tuple[int, float]:
        """(qualifier, interval in s) of a clock, fmi3GetIntervalDecimal."""
        value, qualifier = c_double(), c_int()
        self._check(self._interval(self.inst.component, (c_uint * 1)(clock.vr), 1, byref(value), byref(qualifier)),
                    f"fmi3GetIntervalDecimal ({clock.name})", t)
        return qualifier.value, value.value

    def shift(self, clock: Clock, t: float) -> float:
        value = c_double()
        self._check(self._shift(self.inst.component, (c_uint * 1)(clock.vr), 1, byref(value)),
                    f"fmi3GetShiftDecimal ({clock.name})", t)
        return value.value

    def activate(self, clock: Clock, t: float) -> None:
        self._check(self._activate(self.inst.component, clock.vr, t),
                    f"fmi3ActivateModelPartition ({clock.name}, {t!r})", t)

    def update_until_settled(self, t: float, limit: int = 1000) -> float:
        """fmi3UpdateDiscreteStates until the discrete states settle; the
        next event time the FMU announces (inf when none). Sets the
        instance's ``events.terminated`` when the FMU asks to end."""
        need, term, nominals, values, defined = (c_bool() for _ in range(5))
        next_time = c_double()
        for _ in range(limit):
            self._check(self._update(self.inst.component, byref(need), byref(term), byref(nominals),
                                     byref(values), byref(defined), byref(next_time)),
                        "fmi3UpdateDiscreteStates", t)
            if term.value:
                self.inst.events.terminated = 1
                self.inst.events.end_time = t
            if not need.value:
                return next_time.value if defined.value else math.inf
        raise SimulationError(f"{self.inst.name}: the discrete states did not settle in {limit} "
                              f"fmi3UpdateDiscreteStates calls at t = {t!r} s", time=t, instance=self.inst.name)

    def enter_step_mode(self, t: float) -> None:
        self._check(self._enter_step(self.inst.component), "fmi3EnterStepMode", t)


# fmi3ClockUpdateCallback(instanceEnvironment)
CLOCK_UPDATE = CFUNCTYPE(None, c_void_p)


class ScheduledInstance(Instance3):
    """An FMI 3.0 Scheduled Execution FMU behind the master's calls.

    It has no step: ``c_doStep`` only says OK (its time is the activation
    time of its partitions), and the engine (engine/clocks.py) calls
    fmi3ActivateModelPartition at each tick of each of its input clocks.
    ``clock_updates`` counts the FMU's clockUpdate calls (a countdown
    clock's interval set, an output clock ticked), which the engine
    answers by asking for them after the partition returns."""

    scheduled = True
    CALL_NAMES = {**Instance3.CALL_NAMES, "doStep": "fmi3ActivateModelPartition",
                  "instantiate": "fmi3InstantiateScheduledExecution"}

    def __init__(self, name, path, model_description=None, early_return: bool = True,
                 intermediate_update: bool = False):
        super().__init__(name, path, model_description, False, False)
        self.event_mode_used = False
        self.events.event_mode_used = 0
        self.clock_updates = 0

    def instantiate(self) -> None:
        unzip = extract(self.path)
        from fmpy.fmi3 import FMU3ScheduledExecution
        try:
            self._slave = new_slave(FMU3ScheduledExecution, unzip, self.md, self.name,
                                    self.md.coSimulation.modelIdentifier)
        except Exception as e:  # fmpy raises a bare Exception for a bad library
            raise SceneError(f"{self.shown}: cannot load the FMU's binary for this platform: {e}") from None
        messages = self.messages

        def logger(env, status, category, message):
            messages.append((status, read_string(message)))
            del messages[:-50]

        def clock_update(env):
            self.clock_updates += 1

        self._guard(self._slave.dll, ("fmi3InstantiateScheduledExecution", "fmi3GetVersion"))
        self._log_callback = LOG_MESSAGE(logger)
        self._clock_update = CLOCK_UPDATE(clock_update)
        f = declared(self._slave.dll, "fmi3InstantiateScheduledExecution",
                     (c_char_p, c_char_p, c_char_p, c_bool, c_bool, c_void_p, c_void_p, c_void_p,
                      c_void_p, c_void_p))
        f.restype = c_void_p
        resources = (str(unzip / "resources") + "/").encode()
        component = f(self.name.encode(), self.md.guid.encode(), resources, False, False, None,
                      cast(self._log_callback, c_void_p).value, cast(self._clock_update, c_void_p).value, None, None)
        if not component:
            self.check_crash("fmi3InstantiateScheduledExecution")
            self._forget()
            raise SceneError(f"{self.shown}: fmi3InstantiateScheduledExecution refused the model description's "
                             f"instantiation token {self.md.guid}: {self.last_message() or 'no message'}")
        self._slave.component = component
        self.component = component
        self._bind(self._slave.dll)
        # No step: the time of a Scheduled Execution FMU is its activations'.
        self.c_doStep = lambda comp, t, h, no_set_prior=0: OK

    def core_calls(self, lib) -> tuple[int, tuple[int, ...]]:
        """The FMI 3.0 adapter's calls, but a step that waits (cw_wait_step: no step of its own)."""
        comp, calls = super().core_calls(lib)
        wait = ctypes.cast(lib.cw_wait_step, c_void_p).value
        return comp, tuple(wait if name == "doStep" else f for name, f in zip(CORE_CALLS, calls, strict=True))

