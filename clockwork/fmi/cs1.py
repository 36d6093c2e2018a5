"""The FMI 1.0 Co-Simulation face: an instance of an FMI 1.0 FMU for
Co-Simulation behind the instance contract (``contract.py``).

``Instance1`` answers the contract's calls (``c_doStep(comp, t, h,
flag)``, ``c_getReal(comp, vr, n, out)``...), so that the stepping loop
need not know the version. Behind
them it speaks FMI 1.0 for Co-Simulation, through the FMU's own
``<modelIdentifier>_fmi*`` symbols (fmpy's ``FMU1Slave`` loads the
library):

- the parameters are set after fmiInstantiateSlave, then
  fmiInitializeSlave(tStart, no stop time) does what FMI 2.0's setup,
  initialization mode and its exit do (FMI 1.0 takes no tolerance);
- fmiDoStep takes ``newStep`` (an fmiBoolean: a char), not FMI 2.0's
  noSetFMUStatePriorToCurrentPoint (an int): it is always true, since the
  master never repeats a step of an FMU that has no state to go back to;
  the compiled core calls it through its own correctly typed adapter
  (``cw1_*`` in src_c/master/cw_cs1.c, on this instance's ``_Fmi1``);
- steps run synchronously (no stepFinished callback); an FMU that answers
  fmiPending anyway fails the run in one line, its step cancelled;
- FMI 1.0 computes outputs in fmiDoStep: outputs read after inputs were
  set, with no step between, are computed first by a step of size 0 at the
  communication point (FMI 1.0's iteration, which FMI 2.0 replaced by
  computing them on the get): the master's feedthrough and its algebraic
  loops see the outputs of the inputs it set (``_zero_step``; the core's
  ``cw1_fresh``);
- fmiBoolean values are chars, converted to and from the master's ints;
- a negatedAlias variable shares its value reference with the variable
  it negates: it gets a value reference of its own, above every one the
  FMU uses, which the adapter turns back into the FMU's, negating the
  value (Real, Integer, Boolean) both ways;
- there is no FMU state: the settings that roll every FMU back are refused
  before the first step (master.py, scene.model), and fmiDiscard ends the
  run (FMI 1.0 has no fmiTerminated status);
- fmiTerminateSlave and fmiFreeSlaveInstance end the instance.

The logger gets the FMU's printf format as it is: FMI 1.0's logger has no
environment pointer through which the core's formatting logger could find
this instance.
"""

from __future__ import annotations

import copy
import ctypes
from ctypes import (POINTER, Structure, c_char, c_char_p, c_double, c_int, c_longlong, c_size_t, c_uint,
                    c_void_p)
from pathlib import Path

from fmpy.fmi1 import (FMU1Slave, fmi1CallbackFunctions)

from ..errors import ParametersRefused, SceneError, SimulationError
from .description import fmi1_details, read_fmu
from .archive import extract
from .calls import ERROR, OK, WARNING, fmi1_callbacks
from .contract import CORE_CALLS, Instance

PENDING = 5  # fmiPending: an asynchronous step
TRUE, FALSE = b"\x01", b"\x00"  # fmiBoolean (a char)
MAX_VALUE_REFERENCE = 2**32 - 1


class _Fmi1(Structure):
    """The FMI 1.0 adapter's state, shared with cw_cs1.c's cw_fmi1 (same layout)."""

    _fields_ = [(n, c_void_p) for n in (
        "instance", "doStep", "getReal", "setReal", "setInputDerivatives", "getOutputDerivatives",
        "negated_vr", "base_vr")] + [
        ("time", c_double),         # the FMU's communication point, s
        ("zero_steps", c_longlong),  # steps of size 0 taken to compute outputs
        ("n_negated", c_int),
        ("stale", c_int),           # inputs set since fmiDoStep last computed the outputs
        ("failed_zero", c_int),     # the last zero step failed
        ("pad_", c_int)]


def _free_references(used: set[int], count: int) -> list[int]:
    """`count` value references that no variable uses: above the largest
    used one, else the lowest free ones."""
    top = max(used, default=-1)
    if top + count <= MAX_VALUE_REFERENCE:
        return list(range(top + 1, top + 1 + count))
    free_refs, k = [], 0
    while len(free_refs) < count:
        if k not in used:
            free_refs.append(k)
        k += 1
    return free_refs


def _no_state(comp, state) -> int:
    return ERROR  # never called: the master refuses rollback for FMI 1.0 before the first step


class Instance1(Instance):
    """An instantiated FMI 1.0 Co-Simulation FMU behind the contract's calls."""

    CALL_NAMES = {"doStep": "fmiDoStep", "getReal": "fmiGetReal", "setReal": "fmiSetReal",
                  "getInteger": "fmiGetInteger", "getBoolean": "fmiGetBoolean", "getString": "fmiGetString",
                  "setValues": "fmiSet*", "setInputDerivatives": "fmiSetRealInputDerivatives",
                  "getOutputDerivatives": "fmiGetRealOutputDerivatives",
                  "getState": "saving the FMU state (FMI 1.0 has none)",
                  "setState": "restoring the FMU state (FMI 1.0 has none)", "reset": "fmiResetSlave",
                  "setup": "fmiInitializeSlave", "enterInit": "fmiInitializeSlave",
                  "exitInit": "fmiInitializeSlave", "instantiate": "fmiInstantiateSlave"}

    def __init__(self, name, path, model_description=None):
        super().__init__(name, path, model_description)
        # From the file's own description: one that was unpickled has lost them.
        self.details = fmi1_details(read_fmu(self.path, need_binary=False)[0])
        if self.details.negated:  # renumbered below: copies, not the table its FMU's instances share
            self.variables = {n: copy.copy(v) if n in self.details.negated else v for n, v in self.variables.items()}
        negated = [v for v in self.variables.values() if v.name in self.details.negated]
        used = {v.vr for v in self.variables.values()}
        self._negated: dict[int, int] = {}  # the master's value reference -> the FMU's
        for v, own in zip(negated, _free_references(used, len(negated))):
            self._negated[own] = v.vr
            v.vr = own
        n = len(self._negated)
        self._tables = ((c_uint * max(1, n))(*self._negated), (c_uint * max(1, n))(*self._negated.values()))
        self.adapter = _Fmi1(n_negated=n, negated_vr=ctypes.addressof(self._tables[0]),
                             base_vr=ctypes.addressof(self._tables[1]))
        self._start = 0.0
        self._initialized = self._failed = self._pending = False

    def _outputs_after_inputs(self) -> bool:
        """FMI 1.0 computes outputs in fmiDoStep: a get after a set is served
        by a step of size 0 first (cw1_fresh, FMI 1.0's iteration), never by
        a get on stale outputs; so the master may read after it sets."""
        return True

    # -- loading -------------------------------------------------------

    def instantiate(self) -> None:
        unzip = extract(self.path)
        ident = self.md.coSimulation.modelIdentifier
        try:
            self._slave = FMU1Slave(guid=self.md.guid, unzipDirectory=str(unzip), modelIdentifier=ident,
                                    instanceName=self.name)
        except Exception as e:  # fmpy raises a bare Exception for a bad library, AttributeError for a missing symbol
            raise SceneError(f"{self.path}: cannot load the FMU's binary for this platform: {e}") from None
        callbacks, self._logger = fmi1_callbacks(fmi1CallbackFunctions, self.messages)  # the logger kept from GC
        self._callbacks = callbacks
        callbacks.stepFinished = None  # synchronous steps
        instantiate = self._slave.dll[f"{ident}_fmiInstantiateSlave"]
        instantiate.argtypes = [c_char_p, c_char_p, c_char_p, c_char_p, c_double, c_char, c_char,
                                fmi1CallbackFunctions, c_char]
        instantiate.restype = c_void_p
        self._guard(self._slave.dll, (f"{ident}_fmiInstantiateSlave",))
        component = instantiate(self.name.encode(), self.md.guid.encode(), Path(unzip).as_uri().encode(),
                                self.details.mime_type.encode(), 0.0, FALSE, FALSE, callbacks, FALSE)
        if not component:
            self.check_crash("fmiInstantiateSlave")
            self._slave = None  # nothing to free
            raise SceneError(f"{self.path}: fmiInstantiateSlave made no instance (GUID {self.md.guid}): "
                             f"{self.last_message() or 'it logged no message'}")
        self._slave.component = self.component = component
        self._bind(self._slave.dll)

    def _bind(self, dll) -> None:
        """The FMU's <modelIdentifier>_fmi* symbols, with FMI 1.0's argument types."""
        prefix = f"{self.md.coSimulation.modelIdentifier}_fmi"

        def fn(name, *argtypes):
            f = getattr(dll, prefix + name)
            f.argtypes = list(argtypes)
            f.restype = c_int
            return f

        comp, vrs = c_void_p, POINTER(c_uint)
        f_doStep = fn("DoStep", comp, c_double, c_double, c_char)
        f_getReal = fn("GetReal", comp, vrs, c_size_t, POINTER(c_double))
        f_setReal = fn("SetReal", comp, vrs, c_size_t, POINTER(c_double))
        f_getInteger = fn("GetInteger", comp, vrs, c_size_t, POINTER(c_int))
        f_setInteger = fn("SetInteger", comp, vrs, c_size_t, POINTER(c_int))
        f_getBoolean = fn("GetBoolean", comp, vrs, c_size_t, POINTER(c_char))
        f_setBoolean = fn("SetBoolean", comp, vrs, c_size_t, POINTER(c_char))
        f_getString = fn("GetString", comp, vrs, c_size_t, POINTER(c_char_p))
        f_setString = fn("SetString", comp, vrs, c_size_t, POINTER(c_char_p))
        f_setDer = fn("SetRealInputDerivatives", comp, vrs, c_size_t, POINTER(c_int), POINTER(c_double))
        f_getDer = fn("GetRealOutputDerivatives", comp, vrs, c_size_t, POINTER(c_int), POINTER(c_double))
        self._f_init = fn("InitializeSlave", comp, c_double, c_char, c_double)
        self._f_cancel = fn("CancelStep", comp)
        self._f_terminate = fn("TerminateSlave", comp)
        self._f_free = getattr(dll, prefix + "FreeSlaveInstance")
        self._f_free.argtypes, self._f_free.restype = [comp], None
        self.c_getRealStatus = fn("GetRealStatus", comp, c_int, POINTER(c_double))  # kind 2: fmiLastSuccessfulTime
        self.c_reset = fn("ResetSlave", comp)
        self.c_terminate = self._f_terminate
        self.c_getState = self.c_setState = self.c_freeState = _no_state

        a = self.adapter
        a.instance = self.component
        for field, f in (("doStep", f_doStep), ("getReal", f_getReal), ("setReal", f_setReal),
                         ("setInputDerivatives", f_setDer), ("getOutputDerivatives", f_getDer)):
            setattr(a, field, ctypes.cast(f, c_void_p).value)

        self._f_doStep = f_doStep

        def do_step(comp, t, h, _no_set_prior=1):
            st = f_doStep(comp, t, h, TRUE)
            if st <= WARNING:
                a.time, a.stale = t + h, 0
            return st

        self.c_doStep = do_step
        get_string = lambda comp, vr, n, out: f_getString(comp, self._own(vr, n)[0], n, out)
        set_string = lambda comp, vr, n, values: f_setString(comp, self._own(vr, n)[0], n, values)
        if self._negated:
            getters = (self._numbers_out(f_getReal), self._numbers_out(f_getInteger),
                       self._numbers_out(f_getDer))  # the last: (comp, vr, n, orders, out)
            setters = (self._numbers_in(f_setReal, c_double), self._numbers_in(f_setInteger, c_int))
            self.c_setInputDerivatives = self._numbers_in(f_setDer, c_double)
        else:  # the FMU's own functions: the same shape as FMI 2.0's
            getters, setters = (f_getReal, f_getInteger, f_getDer), (f_setReal, f_setInteger)
            self.c_setInputDerivatives = f_setDer
        self.c_getReal, self.c_getInteger, self.c_getOutputDerivatives, self.c_getBoolean, self.c_getString = (
            self._fresh(f) for f in (*getters, self._booleans_out(f_getBoolean), get_string))
        self.c_setReal, self.c_setInteger, self.c_setBoolean, self.c_setString = (
            self._staling(f) for f in (*setters, self._booleans_in(f_setBoolean), set_string))

    # -- outputs of new inputs: FMI 1.0 computes them in fmiDoStep ---------------

    def _zero_step(self, comp) -> int:
        """Where inputs were set since the last step, a step of size 0 at the
        communication point (FMI 1.0's iteration), which computes the outputs
        of those inputs, as FMI 2.0 does on the get (cw_cs1.c: cw1_fresh)."""
        a = self.adapter
        if not a.stale:
            return OK
        st = self._f_doStep(comp, a.time, 0.0, TRUE)
        if st > WARNING:
            a.failed_zero = 1
            return st
        a.stale = 0
        a.zero_steps += 1
        return st

    def _fresh(self, get):
        def call(comp, *args):
            fresh = self._zero_step(comp)
            if fresh > WARNING:
                return fresh
            return max(get(comp, *args), fresh)
        return call

    def _staling(self, set_):
        def call(comp, vr, n, values):
            st = set_(comp, vr, n, values)
            if n:
                self.adapter.stale = 1
            return st
        return call

    # -- negated aliases and fmiBoolean ---------------------------------------

    def _own(self, vr, n: int):
        """The FMU's value references for the master's `vr` (n of them) and
        the positions of the negated ones."""
        table = self._negated
        if not table:
            return vr, ()
        own = (c_uint * max(1, n))()
        negated = []
        for k in range(n):
            x = vr[k]
            base = table.get(x)
            own[k] = x if base is None else base
            if base is not None:
                negated.append(k)
        return own, negated

    def _numbers_out(self, get):
        def call(comp, vr, n, *rest):
            own, negated = self._own(vr, n)
            st = get(comp, own, n, *rest)
            out = rest[-1]
            for k in negated:
                out[k] = -out[k]
            return st
        return call

    def _numbers_in(self, set_, ctype):
        def call(comp, vr, n, *rest):
            own, negated = self._own(vr, n)
            values = rest[-1]
            if negated:
                values = (ctype * max(1, n))(*values[:n])
                for k in negated:
                    values[k] = -values[k]
            return set_(comp, own, n, *rest[:-1], values)
        return call

    def _booleans_out(self, get):
        def call(comp, vr, n, out):
            own, negated = self._own(vr, n)
            got = (c_char * max(1, n))()
            st = get(comp, own, n, got)
            for k in range(n):
                out[k] = int((got[k] != FALSE) != (k in negated))
            return st
        return call

    def _booleans_in(self, set_):
        def call(comp, vr, n, values):
            own, negated = self._own(vr, n)
            given = (c_char * max(1, n))(*[TRUE if bool(values[k]) != (k in negated) else FALSE for k in range(n)])
            return set_(comp, own, n, given)
        return call

    # -- lifecycle ------------------------------------------------------------

    def setup(self, start: float, parameters: dict[str, object], tolerance: float | None = None) -> None:
        """Parameters, then fmiInitializeSlave from `start` without a stop
        time (FMI 1.0 takes no tolerance: `tolerance` is not passed on)."""
        self._start = start
        self.set_values(parameters, "setting parameters", ParametersRefused)
        self.check(self._f_init(self.component, start, FALSE, 0.0), "fmiInitializeSlave", error=ParametersRefused)
        self._initialized = True
        a = self.adapter
        a.time, a.stale = start, 0  # fmiInitializeSlave computed the outputs of the parameters and start values

    def exit_init(self) -> None:
        """Nothing: fmiInitializeSlave has left initialization already."""

    def reset(self) -> None:
        """fmiResetSlave: back to the state right after instantiation."""
        self.check(self.c_reset(self.component), "fmiResetSlave")
        del self.messages[:]  # an error after the reset must not quote one from before
        self._initialized = self._failed = self._pending = False
        self.adapter.stale = self.adapter.failed_zero = 0

    def terminated(self) -> bool:
        return False  # FMI 1.0 has no fmiTerminated status: a discarded step fails the run

    def core_calls(self, lib) -> tuple[int, tuple[int, ...]]:
        """The core's FMI 1.0 adapter (cw1_*: fmiDoStep's char newStep,
        negated aliases) on this instance's shared ``_Fmi1``."""
        return ctypes.addressof(self.adapter), tuple(
            ctypes.cast(getattr(lib, "cw1_" + name), c_void_p).value for name in CORE_CALLS)

    def fail(self, what, status, time=None, error=None):
        """The error for a failed call (named by its FMI 1.0 name)."""
        self._failed = True
        error = error or SimulationError
        if self.adapter.failed_zero:  # the step of size 0 before the get failed, not the get
            self.adapter.failed_zero = 0
            what = (f"fmiDoStep({self.adapter.time!r}, 0) (a step of size 0, FMI 1.0's way to compute the "
                    f"outputs of inputs set since the last step, before {what.split('(')[0]})")
        if status != PENDING:
            return super().fail(what, status, time, error)
        self._pending = True  # cancelled when the instance is freed
        return error(f"{self.model_name}: {what} returned Pending: an asynchronous step, which clockwork does not "
                     f"wait for (it passes no stepFinished callback)", time=time, instance=self.name)

    def _free_instance(self) -> None:
        comp = self.component
        if self._pending:
            self._f_cancel(comp)
        elif self._initialized and not self._failed:
            self._f_terminate(comp)
        self._f_free(comp)

    def save_state(self, t=None) -> None:
        raise SimulationError(f"{self.name}: FMI 1.0 has no FMU state to save", time=t, instance=self.name)

    restore_state = save_state
