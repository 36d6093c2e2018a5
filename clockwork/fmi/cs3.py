"""The FMI 3.0 Co-Simulation face: an instance of an FMI 3.0 FMU's
Co-Simulation interface behind the instance contract (``contract.py``).

``Instance3`` answers the contract's calls (``c_doStep(comp, t, h,
flag)``, ``c_getReal(comp, vr, n, out)``...), so that master.py,
coupling.py, location.py and checkpoints.py need not know the version.
Behind them it speaks FMI 3.0 and does what FMI 3.0 adds:

- the instance is created with ``eventModeUsed`` when the FMU declares
  ``hasEventMode`` and with ``earlyReturnAllowed`` when it declares
  ``mightReturnEarlyFromDoStep`` (unless ``master.early_return`` is false);
- ``c_doStep`` calls fmi3DoStep; when the FMU returns early at one of its
  own events (``earlyReturn``, ``lastSuccessfulTime``) the event is handled
  there, exactly, and the step goes on from that time to the communication
  point, so that the master needs no rollback for events an FMU owns;
- an event (``eventHandlingNeeded``, and the end of initialization in event
  mode) is handled by fmi3EnterEventMode, fmi3UpdateDiscreteStates until
  ``discreteStatesNeedUpdate`` is false, and fmi3EnterStepMode; the
  ``nextEventTime`` it announces is kept in ``events.next_event_time``,
  where the master caps its step so that a communication point lands on it
  (``events`` is the contract's ``time_events``);
- ``terminateSimulation`` sets ``events.terminated`` and ``events.end_time``
  (the time the FMU reached): when the FMU finished the step, the step
  stands and the master ends the run before the next one; when it stopped
  short, ``c_doStep`` returns Discard and the step is not taken. Either way
  the master ends the run cleanly (``SimulationEnded`` in ``master.ended``,
  as for an FMI 2.0 FMU's fmi2Terminated).

The adapter's state lives in a ctypes struct (``_Events``) that the
compiled core's own adapter (src_c/master/cw_cs3.c)
reads and writes too, so that the two engines hand it over at any point.
Saving and restoring the FMU state saves and restores the announced next
event time with it.

FMI 3.0 Co-Simulation has no input derivatives; its replacement is
intermediate update. When the master gives inputs as polynomials
(extrapolation, strong coupling) and the FMU declares
``providesIntermediateUpdate``, the instance is made with the compiled
core's C callback ``cw3_intermediateUpdate`` (instanceEnvironment: the
``_Events``): ``c_setReal`` and ``c_setInputDerivatives`` go through the
core's ``cw3_setReal``/``cw3_setInputDerivatives``, which keep the
polynomials FMI 2.0 would hand to fmi2SetRealInputDerivatives, and at each
time the FMU asks (its RK stages) the callback sets every input to its
polynomial's value there, with the FMI 2.0 FMU's own arithmetic, so both
builds give the same bits. Both engines use the same callback (never a
Python one). Without it ``c_setInputDerivatives`` fails, and the master
refuses polynomial inputs into the instance before the first step.
"""

from __future__ import annotations

import copy
import ctypes
import math
import weakref
from ctypes import (CFUNCTYPE, POINTER, Structure, byref, c_bool, c_double, c_int, c_longlong, c_size_t, c_uint,
                    c_void_p)

from fmpy.fmi3 import FMU3Slave, fmi3IntermediateUpdateCallback, fmi3LogMessageCallback

from ..errors import SceneError, SimulationError
from ..paths import core_library
from . import layout
from .clocks import clock_table as read_clock_table
from .description import array_elements
from .archive import extract
from .calls import DISCARD, ERROR, NO_SINK, OK, WARNING, declared, formatting_logger, new_slave, read_string
from .contract import CORE_CALLS
from .contract import Instance
from .values3 import Values3
from .variables import Variable

# fmi3LogMessageCallback with the strings as addresses, read by read_string.
LOG_MESSAGE = CFUNCTYPE(None, c_void_p, c_int, c_void_p, c_void_p)

MAX_EVENT_ITERATIONS = 1000  # fmi3UpdateDiscreteStates calls per event before giving up
MAX_STALLED_RETURNS = 100  # early returns in a row that do not move the FMU's time


class _Events(Structure):
    """The FMI 3.0 adapter's state, shared with cw_cs3.c's cw_fmi3 (same layout)."""

    _fields_ = [(n, c_void_p) for n in (
        "instance", "doStep", "getFloat64", "setFloat64", "getOutputDerivatives", "getState", "setState",
        "enterEventMode", "updateDiscreteStates", "enterStepMode")] + [
        ("next_event_time", c_double),        # s; inf when none is announced
        ("saved_next_event_time", c_double),  # with the saved FMU state
        ("end_time", c_double),               # where terminateSimulation stopped the FMU, s
        ("early_returns", c_longlong),
        ("events", c_longlong),               # events handled in event mode
        ("event_mode_used", c_int),
        ("terminated", c_int),
        ("failed_call", c_int),               # 0 none, else which fmi3 call failed (FAILED_CALLS)
        ("pad_", c_int),
        # Intermediate update: the input polynomials (see cw_cs3.c)
        ("n_iu", c_int),
        ("iu_poly", c_int),
        ("iu_vr", c_void_p),
        ("iu_u0", c_void_p),
        ("iu_d1", c_void_p),
        ("iu_d2", c_void_p),
        ("iu_tref", c_void_p),
        ("iu_fed", c_void_p),
        ("iu_set_vr", c_void_p),
        ("iu_val", c_void_p),
        ("iu_time", c_double),
        ("iu_saved_time", c_double),
        ("iu_calls", c_longlong),
        ("iu_saved", c_void_p),
        ("iu_saved_fed", c_void_p),
        # Array elements (see Instance3._number_elements): element code base + k
        # is value k of the array code_vr[k], at code_off[k] of its code_size[k] values.
        ("code_base", c_uint),
        ("n_codes", c_int),
        ("code_vr", c_void_p),
        ("code_off", c_void_p),
        ("code_size", c_void_p),
        ("scratch_vr", c_void_p),     # the value references of one call, translated
        ("scratch_order", c_void_p),  # their derivative orders
        ("scratch_val", c_void_p),    # one array's values (element by element)
        ("scratch_cap", c_int),
        ("scratch_val_cap", c_int),
        ("clock_event", c_void_p),  # with clocks on the compiled core: the master's handler (engine/compiled_clocks.py)
    ]


_core = None


def _core_adapter():
    """The compiled core's intermediate-update functions (callback address,
    cw3_setReal, cw3_setInputDerivatives, cw3_getState, cw3_setState), or
    None without the core."""
    global _core
    if _core is None:
        try:
            lib = ctypes.CDLL(str(core_library()))
            if layout.problem(lib, "cw_layout", "fmi3", _Events):
                raise OSError("another version of the core")
            fns = []
            vrs, doubles = POINTER(c_uint), POINTER(c_double)
            for name, argtypes in (("cw3_setReal", [c_void_p, vrs, c_size_t, doubles]),
                                   ("cw3_setInputDerivatives", [c_void_p, vrs, c_size_t, c_void_p, doubles]),
                                   ("cw3_getState", [c_void_p, POINTER(c_void_p)]),
                                   ("cw3_setState", [c_void_p, c_void_p])):
                f = getattr(lib, name)
                f.argtypes = argtypes
                f.restype = c_int
                fns.append(f)
            _core = (ctypes.cast(lib.cw3_intermediateUpdate, c_void_p).value, *fns)
        except (OSError, AttributeError):
            _core = False
    return _core or None


# What _Events.failed_call names (the same numbers in cw_cs3.c).
FAILED_CALLS = {1: "fmi3DoStep", 2: "fmi3EnterEventMode", 3: "fmi3UpdateDiscreteStates",
                4: "fmi3EnterStepMode", 5: "fmi3DoStep (early returns that do not move time)",
                6: "fmi3UpdateDiscreteStates (discrete states did not settle)"}


class Instance3(Instance):
    """An instantiated FMI 3.0 Co-Simulation FMU behind the contract's calls."""

    clock_event = None  # with clocks: the engine's handler of an event the FMU signals, (time) -> status

    def clock_table(self):
        return read_clock_table(self.md) or None

    CALL_NAMES = {"doStep": "fmi3DoStep", "getReal": "fmi3GetFloat64", "setReal": "fmi3SetFloat64",
                  "getInteger": "fmi3GetInt32", "getBoolean": "fmi3GetBoolean", "getString": "fmi3GetString",
                  "setValues": "fmi3Set*", "setInputDerivatives": "the input polynomials (intermediate update)",
                  "getOutputDerivatives": "fmi3GetOutputDerivatives", "getState": "fmi3GetFMUState",
                  "setState": "fmi3SetFMUState", "reset": "fmi3Reset", "setup": "fmi3EnterInitializationMode",
                  "enterInit": "fmi3EnterInitializationMode", "exitInit": "fmi3ExitInitializationMode",
                  "instantiate": "fmi3InstantiateCoSimulation"}

    def __init__(self, name, path, model_description=None, early_return: bool = True,
                 intermediate_update: bool = False):
        super().__init__(name, path, model_description)
        cs = self.md.coSimulation
        self.event_mode_used = self.has_event_mode = bool(cs.hasEventMode)
        self.early_return_allowed = bool(cs.mightReturnEarlyFromDoStep) and early_return
        # Inputs as polynomials through intermediate update, when asked for
        # (the master's inputs are polynomials), declared, and the core's
        # callback is at hand; else none (FMI 3.0 CS has no input derivatives).
        iu_vrs = [v.valueReference for v in self.md.modelVariables
                  if v.causality == "input" and v.type == "Real" and v.intermediateUpdate and not v.shape]
        declared = bool(cs.providesIntermediateUpdate and iu_vrs)
        self.intermediate_update = bool(intermediate_update and declared and _core_adapter())
        self.can_interpolate_inputs = self.intermediate_update
        # Why polynomial inputs cannot reach this instance (the master's refusal says it).
        self.no_intermediate_update = (
            "" if self.intermediate_update else
            f"the compiled core {core_library()}, which serves its intermediate update, cannot be loaded "
            f"(build it with tools/setup.sh)" if intermediate_update and declared else
            "it provides no intermediate update")
        self.events = _Events(next_event_time=math.inf, saved_next_event_time=math.inf, end_time=math.nan,
                              event_mode_used=int(self.event_mode_used))
        self.time_events = self.events  # the contract's name: the core and the master read it
        self._number_elements()
        self._setup_args = (0, 0.0, 0.0, 0, 0.0)
        if self.intermediate_update:
            n = len(iu_vrs)
            self._iu_arrays = ((c_uint * n)(*iu_vrs), (c_double * n)(), (c_double * n)(), (c_double * n)(),
                               (c_double * n)(), (c_int * n)(), (c_uint * n)(), (c_double * n)(),
                               (c_double * (4 * n))(), (c_int * n)())
            ev = self.events
            ev.n_iu = n
            for field, arr in zip(("iu_vr", "iu_u0", "iu_d1", "iu_d2", "iu_tref", "iu_fed", "iu_set_vr", "iu_val",
                                   "iu_saved", "iu_saved_fed"), self._iu_arrays):
                setattr(ev, field, ctypes.addressof(arr))

    def _number_elements(self) -> None:
        """Give each element of an array variable a Variable of its own
        (``y[0]``, ``A[1,2]``) whose vr is a code of its own, above every value
        reference of the FMU: the master's ports name elements as it names
        scalars, and the contract's calls (here and in cw_cs3.c's cw3_*)
        turn a run of codes that covers a whole array, in order, into the
        array's value reference with nValues > nValueReferences; any other
        request is served element by element. Dependencies on an array
        input are on each of its elements."""
        arrays = [v for v in self.md.modelVariables if v.shape]
        self.arrays: dict[str, tuple[int, int]] = {}  # array name -> (vr, number of values)
        self.elements: dict[str, list[str]] = {}  # array name -> element names, row-major
        if not arrays:
            return
        # Its own table: the elements and their dependencies are added to a
        # copy of the one its FMU's instances share (fmu.instance_variables).
        self.variables = {n: copy.copy(v) for n, v in self.variables.items()}
        base = max(v.valueReference for v in self.md.modelVariables) + 1
        code_vr, code_off, code_size = [], [], []
        for v in arrays:
            var = self.variables[v.name]
            var.shape = tuple(v.shape)
            size = len(array_elements(v))
            self.arrays[v.name] = (v.valueReference, size)
            self.elements[v.name] = [e.name for e in array_elements(v)]
            for e in array_elements(v):
                self.variables[e.name] = Variable(e.name, base + len(code_vr), var.type, var.causality,
                                                  var.variability, var.unit, var.dependencies, (), v.name, e.index)
                code_vr.append(v.valueReference)
                code_off.append(e.index)
                code_size.append(size)
        if base + len(code_vr) > 2**32:
            raise SceneError(f"{self.shown}: the value references leave no room to number the array elements")
        elements = self.elements
        for var in self.variables.values():
            if var.dependencies and any(d in elements for d in var.dependencies):
                var.dependencies = [x for d in var.dependencies for x in elements.get(d, [d])]
        n = len(code_vr)
        cap = 2 * len(self.variables) + 2
        largest = max(code_size, default=1)
        self._code_arrays = ((c_uint * n)(*code_vr), (c_int * n)(*code_off), (c_int * n)(*code_size),
                             (c_uint * cap)(), (c_int * cap)(), (c_double * max(1, largest))())
        ev = self.events
        ev.code_base, ev.n_codes, ev.scratch_cap, ev.scratch_val_cap = base, n, cap, max(1, largest)
        for field, arr in zip(("code_vr", "code_off", "code_size", "scratch_vr", "scratch_order", "scratch_val"),
                              self._code_arrays):
            setattr(ev, field, ctypes.addressof(arr))

    def _runs(self, vr, n: int, order=None):
        """(value references, orders) of a request of n codes made of scalars
        and whole arrays in order (each array's orders alike), or None."""
        ev = self.events
        base, n_codes = ev.code_base, ev.n_codes
        code_vr, code_off, code_size = self._code_arrays[:3]
        vrs, orders = [], []
        k = 0
        while k < n:
            c = vr[k]
            e = c - base
            if 0 <= e < n_codes:
                size = code_size[e]
                if code_off[e] or k + size > n or any(vr[k + i] != c + i for i in range(1, size)) or (
                        order is not None and any(order[k + i] != order[k] for i in range(1, size))):
                    return None
                vrs.append(code_vr[e])
            else:
                size = 1
                vrs.append(c)
            if order is not None:
                orders.append(order[k])
            k += size
        return vrs, orders

    def _array_call(self, call, comp, vr, n, values, order=None, writing=False) -> int:
        """fmi3Get/SetFloat64 (call(comp, vrs, nvr, values, nValues)) or, with
        `order`, fmi3GetOutputDerivatives (call(comp, vrs, nvr, orders,
        values, nValues)) on a request of codes (see _number_elements)."""
        runs = self._runs(vr, n, order)
        if runs is not None:
            vrs, orders = runs
            m = len(vrs)
            if order is None:
                return call(comp, (c_uint * max(1, m))(*vrs), m, values, n)
            return call(comp, (c_uint * max(1, m))(*vrs), m, (c_int * max(1, m))(*orders), values, n)
        if writing:  # a part of an array cannot be set (the ports set whole arrays)
            self.messages.append((ERROR, "clockwork: a request sets part of an array variable"))
            return ERROR
        ev = self.events
        code_vr, code_off, code_size = self._code_arrays[:3]
        buf = self._code_arrays[5]
        worst = OK
        for k in range(n):
            c = vr[k]
            e = c - ev.code_base
            one = (c_uint * 1)(code_vr[e] if 0 <= e < ev.n_codes else c)
            size = code_size[e] if 0 <= e < ev.n_codes else 1
            if order is None:
                st = call(comp, one, 1, buf, size)
            else:
                st = call(comp, one, 1, (c_int * 1)(order[k]), buf, size)
            worst = max(worst, st)
            if st > WARNING:
                return st
            values[k] = buf[code_off[e] if 0 <= e < ev.n_codes else 0]
        return worst

    def instantiate(self) -> None:
        unzip = extract(self.path)
        try:
            self._slave = new_slave(FMU3Slave, unzip, self.md, self.name, self.md.coSimulation.modelIdentifier)
        except Exception as e:  # fmpy raises a bare Exception for a bad library
            raise SceneError(f"{self.shown}: cannot load the FMU's binary for this platform: {e}") from None
        messages = self.messages

        def logger(env, status, category, message):
            # Addresses, read without trusting them; env is not used.
            messages.append((status, read_string(message)))
            del messages[:-50]

        self._register_env()
        self._guard(self._slave.dll, ("fmi3InstantiateCoSimulation", "fmi3GetVersion"))
        try:
            self._instantiate(logger)
        except Exception as e:
            self.check_crash("fmi3InstantiateCoSimulation")
            refusal = self.last_message() or str(e)
            if not self.event_mode_used:
                self._forget()
                raise SceneError(
                    f"{self.shown}: fmi3InstantiateCoSimulation refused the model description's instantiation "
                    f"token {self.md.guid}: {refusal}") from None
            # An FMU that declares hasEventMode but refuses eventModeUsed (Reference-FMUs' Roberts):
            # instantiated as fmpy does, without Event Mode (the FMU then handles its events inside
            # fmi3DoStep), and said in a note.
            self.event_mode_used = self.has_event_mode = False
            self.events.event_mode_used = 0
            try:
                self._instantiate(logger)
            except Exception:
                self._forget()
                raise SceneError(
                    f"{self.shown}: fmi3InstantiateCoSimulation refused the model description's instantiation "
                    f"token {self.md.guid}, with Event Mode ({refusal}) and without it "
                    f"({self.last_message() or 'no message'})") from None
            self.instantiation_note = (f"{self.name} declares hasEventMode but refused eventModeUsed at "
                                       f"instantiation ({refusal}): it runs without Event Mode, its events "
                                       f"handled inside fmi3DoStep")
        self.component = self._slave.component
        self._bind(self._slave.dll)

    def _register_env(self) -> None:
        """Put this instance's ``_Events`` (the instanceEnvironment) into the
        core's registry of live environments: cw3_intermediateUpdate serves
        only an environment found there, whatever pointer the FMU passes."""
        core = formatting_logger()
        if core is not None:
            env = ctypes.addressof(self.events)
            core[1].cw_env_register(env, self.name.encode("utf-8", "replace"), NO_SINK)
            self._forget_env = weakref.finalize(self, core[1].cw_env_unregister, env)

    def _instantiate(self, logger) -> None:
        """fmi3InstantiateCoSimulation with this instance's ``_Events`` as its
        environment, the core's C intermediate-update callback when inputs go
        through it, and a logger that takes the FMU's strings as addresses
        (fmpy's type would read them, whatever they point at)."""
        slave = self._slave
        self._log_callback = LOG_MESSAGE(logger)  # kept from GC
        slave.logMessage = ctypes.cast(self._log_callback, fmi3LogMessageCallback)
        slave.intermediateUpdate = (fmi3IntermediateUpdateCallback(_core_adapter()[0]) if self.intermediate_update
                                    else fmi3IntermediateUpdateCallback())
        resources = str(extract(self.path) / "resources") + "/"
        slave.component = slave.fmi3InstantiateCoSimulation(
            self.name.encode(), self.md.guid.encode(), resources.encode(), False, False,
            self.event_mode_used, self.early_return_allowed, None, 0, ctypes.addressof(self.events),
            slave.logMessage, slave.intermediateUpdate)
        if not slave.component:
            raise Exception("Failed to instantiate FMU")

    def _bind(self, dll) -> None:
        def fn(name, *argtypes):
            return declared(dll, name, argtypes)

        inst = c_void_p
        vrs = POINTER(c_uint)
        pb = POINTER(c_bool)
        f_doStep = fn("fmi3DoStep", inst, c_double, c_double, c_bool, pb, pb, pb, POINTER(c_double))
        f_getF64 = fn("fmi3GetFloat64", inst, vrs, c_size_t, POINTER(c_double), c_size_t)
        f_setF64 = fn("fmi3SetFloat64", inst, vrs, c_size_t, POINTER(c_double), c_size_t)
        f_getI32 = fn("fmi3GetInt32", inst, vrs, c_size_t, POINTER(c_int), c_size_t)
        f_setI32 = fn("fmi3SetInt32", inst, vrs, c_size_t, POINTER(c_int), c_size_t)
        f_getBool = fn("fmi3GetBoolean", inst, vrs, c_size_t, pb, c_size_t)
        f_setBool = fn("fmi3SetBoolean", inst, vrs, c_size_t, pb, c_size_t)
        f_getDer = fn("fmi3GetOutputDerivatives", inst, vrs, c_size_t, POINTER(c_int), POINTER(c_double), c_size_t)
        f_getState = fn("fmi3GetFMUState", inst, POINTER(c_void_p))
        f_setState = fn("fmi3SetFMUState", inst, c_void_p)
        f_enterEvent = fn("fmi3EnterEventMode", inst)
        f_update = fn("fmi3UpdateDiscreteStates", inst, pb, pb, pb, pb, pb, POINTER(c_double))
        f_enterStep = fn("fmi3EnterStepMode", inst)
        f_enterInit = fn("fmi3EnterInitializationMode", inst, c_bool, c_double, c_double, c_bool, c_double)
        self._f = (f_doStep, f_enterEvent, f_update, f_enterStep)
        # Values of every type: bound here, the contract's calls without a
        # Python call of their own (a discrete link gets and sets every step).
        self._values = Values3(self, dll)
        self.get_values, self.set_values = self._values.get_values, self._values.set_values

        ev = self.events
        ev.instance = self.component
        for field, f in (("doStep", f_doStep), ("getFloat64", f_getF64), ("setFloat64", f_setF64),
                         ("getOutputDerivatives", f_getDer), ("getState", f_getState), ("setState", f_setState),
                         ("enterEventMode", f_enterEvent), ("updateDiscreteStates", f_update),
                         ("enterStepMode", f_enterStep)):
            setattr(ev, field, ctypes.cast(f, c_void_p).value)

        self.c_doStep = self._do_step
        self.c_getReal = lambda comp, vr, n, out: f_getF64(comp, vr, n, out, n)
        self.c_setReal = lambda comp, vr, n, val: f_setF64(comp, vr, n, val, n)
        if self.arrays:  # requests name array elements by their codes
            array_call = self._array_call
            self.c_getReal = lambda comp, vr, n, out: array_call(f_getF64, comp, vr, n, out)
            self.c_setReal = lambda comp, vr, n, val: array_call(f_setF64, comp, vr, n, val, writing=True)
        self.c_getInteger = lambda comp, vr, n, out: f_getI32(comp, vr, n, out, n)
        self.c_setInteger = lambda comp, vr, n, val: f_setI32(comp, vr, n, val, n)

        def get_boolean(comp, vr, n, out):
            got = (c_bool * max(1, n))()
            st = f_getBool(comp, vr, n, got, n)
            for k in range(n):
                out[k] = int(got[k])
            return st

        self.c_getBoolean = get_boolean
        self.c_setBoolean = lambda comp, vr, n, val: f_setBool(comp, vr, n, (c_bool * max(1, n))(*val[:n]), n)
        self.c_getOutputDerivatives = lambda comp, vr, n, orders, out: f_getDer(comp, vr, n, orders, out, n)
        if self.arrays:
            self.c_getOutputDerivatives = lambda comp, vr, n, orders, out: self._array_call(
                f_getDer, comp, vr, n, out, order=orders)
        self.c_setInputDerivatives = self._no_input_derivatives
        self.c_getState = f_getState
        self.c_setState = f_setState
        if self.intermediate_update:
            # The core's adapter keeps the polynomials (and saves them with the FMU state).
            _, cw3_set, cw3_set_der, cw3_get_state, cw3_set_state = _core_adapter()
            here = ctypes.addressof(ev)
            self.c_setReal = lambda comp, vr, n, val: cw3_set(here, vr, n, val)
            self.c_setInputDerivatives = lambda comp, vr, n, orders, der: cw3_set_der(here, vr, n, orders, der)
            self.c_getState = lambda comp, state: cw3_get_state(here, state)
            self.c_setState = lambda comp, state: cw3_set_state(here, state)
        self.c_freeState = fn("fmi3FreeFMUState", inst, POINTER(c_void_p))
        self.c_reset = fn("fmi3Reset", inst)
        self.c_terminate = fn("fmi3Terminate", inst)
        exit_init = fn("fmi3ExitInitializationMode", inst)

        def setup(comp, tol_defined, tol, start, stop_defined, stop):
            self._setup_args = (tol_defined, tol, start, stop_defined, stop)
            self.events.iu_time = start
            return OK  # FMI 3.0 takes these when initialization mode is entered

        def enter_init(comp):
            return f_enterInit(comp, *self._setup_args)

        def exit_and_settle(comp):
            st = exit_init(comp)
            if st <= WARNING and self.event_mode_used:
                # In event mode after initialization: settle the discrete states.
                st = max(st, self._settle(comp))
            return st

        self.c_setup, self.c_enterInit, self.c_exitInit = setup, enter_init, exit_and_settle

    # -- values of every type: values3.Values3, bound in _bind ------------------

    def _no_input_derivatives(self, comp, vr, n, orders, der) -> int:
        self.messages.append((ERROR, "FMI 3.0 Co-Simulation has no input derivatives"))
        return ERROR

    # -- the step, with the events FMI 3.0 reports ------------------------------

    def _handle_event(self, comp) -> int:
        """Event mode: update the discrete states until they settle, then step mode."""
        st = self._f[1](comp)
        if st > WARNING:
            self.events.failed_call = 2
            return st
        return max(st, self._settle(comp))

    def _settle(self, comp) -> int:
        """In event mode: fmi3UpdateDiscreteStates until the discrete states
        settle, keep the next event time, then fmi3EnterStepMode."""
        _, _, update, enter_step = self._f
        ev = self.events
        st = OK
        need, term, nominals, values, defined = (c_bool() for _ in range(5))
        next_time = c_double()
        for _ in range(MAX_EVENT_ITERATIONS):
            s = update(comp, byref(need), byref(term), byref(nominals), byref(values), byref(defined),
                       byref(next_time))
            st = max(st, s)
            if s > WARNING:
                ev.failed_call = 3
                return s
            if term.value:
                ev.terminated = 1
            if not need.value:
                break
        else:
            ev.failed_call = 6
            return ERROR
        ev.next_event_time = next_time.value if defined.value else math.inf
        ev.events += 1
        s = enter_step(comp)
        if s > WARNING:
            ev.failed_call = 4
        return max(st, s)

    def _do_step(self, comp, t: float, h: float, no_set_prior: int = 0) -> int:
        """fmi3DoStep from t to t + h, through the FMU's own events."""
        do_step = self._f[0]
        ev = self.events
        end = t + h
        now, step = t, h
        handling, term, early = c_bool(), c_bool(), c_bool()
        last = c_double()
        worst = OK
        stalled = 0
        while True:
            st = do_step(comp, now, step, bool(no_set_prior), byref(handling), byref(term), byref(early), byref(last))
            if st > WARNING:
                ev.failed_call = 1
                return st
            worst = max(worst, st)
            reached = last.value if early.value else end
            if handling.value and self.event_mode_used:
                # An FMU with clocks: the clock engine handles the event (engine/clocks.py).
                st = self._handle_event(comp) if self.clock_event is None else self.clock_event(reached)
                if st > WARNING:
                    return st
                worst = max(worst, st)
            if term.value:
                reached = last.value  # where the FMU stopped, early return or not
            if term.value or ev.terminated:
                # A whole step is kept (the master ends the run at its next
                # step); one the FMU stopped short of is discarded.
                ev.terminated = 1
                ev.end_time = reached
                return worst if reached >= end else DISCARD
            if not early.value or reached >= end:
                ev.iu_time = end  # the FMU's time, where inputs set next are anchored
                return worst
            ev.early_returns += 1
            stalled = stalled + 1 if reached <= now else 0
            if stalled > MAX_STALLED_RETURNS:
                ev.failed_call = 5
                return ERROR
            now, step = reached, end - reached
            # The FMU's step must end on `end` itself (now + step rounds),
            # so that it lands where a step without early return lands.
            while now + step < end:
                step = math.nextafter(step, math.inf)
            while now + step > end:
                step = math.nextafter(step, 0.0)

    # -- lifecycle --------------------------------------------------------------

    def reset(self) -> None:
        super().reset()
        ev = self.events
        ev.next_event_time = ev.saved_next_event_time = math.inf
        ev.end_time = math.nan
        ev.terminated = ev.failed_call = 0
        if self.intermediate_update:  # the inputs are the start values again
            ctypes.memset(self._iu_arrays[5], 0, ctypes.sizeof(self._iu_arrays[5]))
            ev.iu_poly = 0

    def save_state(self, t: float | None = None) -> None:
        super().save_state(t)
        self.events.saved_next_event_time = self.events.next_event_time

    def restore_state(self, t: float | None = None) -> None:
        super().restore_state(t)
        self.events.next_event_time = self.events.saved_next_event_time

    def _free_instance(self) -> None:
        self._slave.fmi3FreeInstance(self.component)

    def fail(self, what, status, time=None, error=None):
        """The error for a failed call; a failed step names the fmi3 call
        inside it that failed (an event's fmi3UpdateDiscreteStates...)."""
        call = FAILED_CALLS.get(self.events.failed_call)
        if call and what.startswith("fmi3DoStep"):
            what = call + what[len("fmi3DoStep"):]
        self.events.failed_call = 0
        return super().fail(what, status, time, error or SimulationError)

    def core_calls(self, lib) -> tuple[int, tuple[int, ...]]:
        """The core's FMI 3.0 adapter (cw3_*) on this instance's shared ``_Events``."""
        return ctypes.addressof(self.events), tuple(
            ctypes.cast(getattr(lib, "cw3_" + name), c_void_p).value for name in CORE_CALLS)

    def polynomial_inputs_refusal(self, fix: str) -> str | None:
        """FMI 3.0 Co-Simulation takes no input derivatives: polynomial inputs
        only through intermediate update."""
        if self.can_interpolate_inputs:
            return None
        why = self.no_intermediate_update or "it provides no intermediate update"
        return (f"is an FMI 3.0 FMU, whose Co-Simulation interface takes no input derivatives, and {why}; "
                f"use {fix} or an FMI 2.0 build")

