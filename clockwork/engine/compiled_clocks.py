"""FMI 3.0 clocks on the compiled core (src_c/master/cw_clocks.c).

The core steps a scene with clocks as any other: it keeps the next tick of
every input clock the master ticks (``_Clocks.next``), cuts a step that
would pass one, and returns ``CLOCK_EVENT`` where a step ends at an event
of the clocks (a tick, an event an FMU signalled inside its step, a located
state event where FMUs have output clocks). The event itself (Event Mode or
Scheduled Execution, the records) is ClockedMaster's (engine/clocks.py):
the same calls in the same order with the same values, so both engines
give the same bits. An event an FMU signals inside its step reaches the
same handler through the FMI 3.0 adapter's ``clock_event`` pointer.

``CoreClocks`` is the part of ``compiled.CompiledClockedMaster`` that does
this; it names no class of compiled.py (which imports it).
"""

from __future__ import annotations

import ctypes
from ctypes import CFUNCTYPE, Structure, c_double, c_int, c_void_p

from .master import Master

CLOCK_EVENT = 6  # CW_CLOCK_EVENT in cw_master.h
FMI_ERROR = 3

# The adapter's clock_event: int (*)(double t)
CLOCK_EVENT_CALL = CFUNCTYPE(c_int, c_double)


class _Clocks(Structure):
    """cw_clocks (cw_structs.h): the input clocks' next ticks, s, and the event flags."""

    _fields_ = [("next", c_void_p), ("n_next", c_int), ("asked", c_int), ("pending", c_int), ("due", c_int)]



class CoreClocks:
    """ClockedMaster's step on the compiled core (see the module's docstring)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._clock_error: BaseException | None = None
        self._cclocks = _Clocks(asked=int(bool(self._asked)))
        self._next_arr = (c_double * 1)()
        self._core.clocks = ctypes.addressof(self._cclocks)
        for n in self.tables:
            inst = self.instances[n]
            if inst.clock_event is not None:
                inst.time_events.clock_event = ctypes.cast(self._core_handler(inst), c_void_p).value

    # The master's flags live in the core; before it exists (inside
    # Master.__init__) they go to the instance dict.
    def _flag(name: str):  # noqa: N805 (a property factory in the class body)
        def get(self):
            core = self.__dict__.get("_core")
            return self.__dict__["_pre_" + name] if core is None else bool(getattr(core, name))

        def put(self, value):
            core = self.__dict__.get("_core")
            if core is None:
                self.__dict__["_pre_" + name] = value
            else:
                setattr(core, name, int(value))
        return property(get, put)

    after_event = _flag("after_event")
    after_event_step = _flag("after_event_step")
    del _flag

    def _core_handler(self, inst):
        """The C adapter's clock_event for `inst`: the Python engine's
        handler, its error kept for the core's return (a callback cannot
        raise through C)."""
        handle = inst.clock_event

        def call(t: float) -> int:
            try:
                st = handle(t)
            except BaseException as e:  # noqa: BLE001 (raised again when the core returns)
                self._clock_error = e
                return FMI_ERROR
            self._cclocks.pending = int(bool(self._pending))
            self._sync_ticks()
            return st

        inst._core_clock_event = CLOCK_EVENT_CALL(call)  # alive as long as the instance
        return inst._core_clock_event

    def _sync_ticks(self) -> None:
        """The schedules' next ticks into the core's table."""
        schedules = self._schedules
        if len(self._next_arr) != max(1, len(schedules)):
            self._next_arr = (c_double * max(1, len(schedules)))()
        arr = self._next_arr
        for i, s in enumerate(schedules):
            arr[i] = s.next
        self._cclocks.next = ctypes.addressof(arr)
        self._cclocks.n_next = len(schedules)

    def initialize(self, parameters) -> None:
        super().initialize(parameters)
        self._sync_ticks()

    def step(self, h: float) -> float:
        self._pending = []
        rc = self._lib.cw_step(self._core_ptr, h, self._taken_ptr)
        if self._core.orders_lowered:
            self._orders_lowered()
        if rc and rc != CLOCK_EVENT:
            self._handle(rc)
        if self.on_step is not None:
            self.on_step(self)
        self._at_core_point()
        return self._taken.value

    def _at_core_point(self) -> None:
        """Where the core's step ended at an event of the clocks: ClockedMaster's."""
        if self._cclocks.due:
            self.at_point()
            self._sync_ticks()

    def _handle(self, rc: int) -> None:
        err, self._clock_error = self._clock_error, None
        if err is not None:
            raise err
        super()._handle(rc)

    def _run_marks(self, t_stop, marks, on_rows):
        return Master._run_marks(self, t_stop, marks, on_rows)  # the Python loop over compiled steps
