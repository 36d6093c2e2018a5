"""The FMI 1.0 Model Exchange face: an FMI 1.0 FMU's Model Exchange
functions, for the engine's wrapper (``engine/model_exchange.py``), which
composes it with an integrator and implements the instance contract.

As ``me2.ModelExchange2``, in FMI 1.0's calls, named
``<modelIdentifier>_fmiXxx``. What FMI 1.0 differs in, and how the face
gives the wrapper its FMI 2.0-shaped algorithm anyway:

- fmiInstantiateModel takes the callbacks (logger, allocateMemory,
  freeMemory: no stepFinished, no environment) by value;
- fmiInitialize is FMI 2.0's initialization mode, its exit and the first
  event iteration in one call, with the relative tolerance; the face calls
  it at the wrapper's ``exitInit`` and hands its eventInfo to the
  wrapper's first update (no fmiEventUpdate follows an initialization that
  has settled already); the start time goes in first through fmiSetTime;
- there is no event mode and no continuous-time mode: fmiEventUpdate
  handles an event from the stepping state, and the face's entering of
  either mode is a call that does nothing (a C function pointer, so the
  compiled core calls it as it calls FMI 2.0's);
- fmiEventUpdate(intermediateResults = false) iterates until the discrete
  states settle and fills fmiEventInfo: iterationConverged (false: the
  wrapper updates again), stateValueReferencesChanged (the states are
  others: read again, with their nominals), stateValuesChanged,
  terminateSimulation, upcomingTimeEvent and nextEventTime;
- fmiCompletedIntegratorStep(callEventUpdate) must be called after every
  completed integrator step (FMI 1.0 has no flag to skip it) and cannot
  end the simulation itself;
- fmiBoolean is a char, converted to and from the wrapper's ints;
- there is no FMU state (no fmiGetFMUstate): the wrapper says it cannot
  get and set it (``can_get_set_state`` false), so the settings that roll
  every FMU back are refused before the first step (master.py,
  scene.model; ``description.no_state_reason``), as for FMI 1.0
  Co-Simulation; the face's get and set of the state fail if called;
- there is no reset: a run that needs one (shooting) fails in one line;
- fmiTerminate and fmiFreeModelInstance end the instance.
"""

from __future__ import annotations

from ctypes import CFUNCTYPE, POINTER, Structure, byref, c_char, c_char_p, c_double, c_int, c_size_t, c_uint, c_void_p

from fmpy.fmi1 import FMU1Model, fmi1CallbackAllocateMemoryTYPE, fmi1CallbackFreeMemoryTYPE, fmi1CallbackLoggerTYPE

from ..errors import SceneError
from .archive import extract
from .calls import ERROR, OK, fmi1_callbacks
from .me_values import value_calls

TRUE, FALSE = b"\x01", b"\x00"  # fmiBoolean (a char)


class CallbacksME1(Structure):
    """FMI 1.0 Model Exchange's fmiCallbackFunctions (no stepFinished)."""

    _fields_ = [("logger", fmi1CallbackLoggerTYPE), ("allocateMemory", fmi1CallbackAllocateMemoryTYPE),
                ("freeMemory", fmi1CallbackFreeMemoryTYPE)]


class EventInfo1(Structure):
    """FMI 1.0's fmiEventInfo (fmiBoolean: a char)."""

    _fields_ = [("iterationConverged", c_char), ("stateValueReferencesChanged", c_char),
                ("stateValuesChanged", c_char), ("terminateSimulation", c_char), ("upcomingTimeEvent", c_char),
                ("nextEventTime", c_double)]


def _flag(value: bytes) -> bool:
    return value != FALSE


# The modes FMI 1.0 does not have, and its missing FMU state: C function
# pointers (the compiled core calls them as FMI 2.0's), made once.
_MODE = CFUNCTYPE(c_int, c_void_p)
_GET_STATE = CFUNCTYPE(c_int, c_void_p, POINTER(c_void_p))
_SET_STATE = CFUNCTYPE(c_int, c_void_p, c_void_p)
NO_MODE = _MODE(lambda comp: OK)
NO_GET_STATE = _GET_STATE(lambda comp, state: ERROR)
NO_SET_STATE = _SET_STATE(lambda comp, state: ERROR)


class ModelExchange1:
    """The FMI 1.0 Model Exchange functions of one instance (see the module's docstring)."""

    CORE_CALLS_TABLE = "cwme_calls_fmi1"  # cw_me.c's table of this version's calls whose shape differs
    CALL_NAMES = {"doStep": "the Model Exchange step", "getReal": "fmiGetReal", "setReal": "fmiSetReal",
                  "getInteger": "fmiGetInteger", "getBoolean": "fmiGetBoolean", "getString": "fmiGetString",
                  "setValues": "fmiSet*", "setInputDerivatives": "input derivatives of the Model Exchange wrapper",
                  "getOutputDerivatives": "output derivatives of the Model Exchange wrapper",
                  "getState": "saving the FMU state (FMI 1.0 has none)",
                  "setState": "restoring the FMU state (FMI 1.0 has none)",
                  "reset": "resetting the FMU (FMI 1.0 Model Exchange has no reset)",
                  "setup": "fmiSetTime", "enterInit": "fmiInitialize", "exitInit": "fmiInitialize",
                  "instantiate": "fmiInstantiateModel"}
    NAMES = {"setTime": "fmiSetTime", "setStates": "fmiSetContinuousStates",
             "getDerivatives": "fmiGetDerivatives", "getIndicators": "fmiGetEventIndicators",
             "completedStep": "fmiCompletedIntegratorStep", "enterEventMode": "fmiEventUpdate",
             "update": "fmiEventUpdate", "enterContinuousMode": "fmiEventUpdate",
             "getStates": "fmiGetContinuousStates", "getNominals": "fmiGetNominalContinuousStates",
             "setReal": "fmiSetReal"}
    values = None  # values of every type go through the contract's typed calls (get_integer...)

    def instantiate(self, owner):
        """Load and instantiate the FMU for `owner` (the wrapper: its name,
        messages, crash guard); returns fmpy's model object."""
        md = owner.md
        ident = md.modelExchange.modelIdentifier
        unzip = extract(owner.path)
        try:
            slave = FMU1Model(guid=md.guid, unzipDirectory=str(unzip), modelIdentifier=ident,
                              instanceName=owner.name)
        except Exception as e:  # fmpy raises a bare Exception for a bad library, AttributeError for a missing symbol
            raise SceneError(f"{owner.shown}: cannot load the FMU's binary for this platform: {e}") from None
        callbacks, self._logger = fmi1_callbacks(CallbacksME1, owner.messages)  # the logger kept from GC
        self._callbacks = callbacks
        instantiate = slave.dll[f"{ident}_fmiInstantiateModel"]
        instantiate.argtypes = [c_char_p, c_char_p, CallbacksME1, c_char]
        instantiate.restype = c_void_p
        owner._guard(slave.dll, (f"{ident}_fmiInstantiateModel",))
        component = instantiate(owner.name.encode(), md.guid.encode(), callbacks, FALSE)
        if not component:
            owner.check_crash("fmiInstantiateModel")
            raise SceneError(f"{owner.shown}: fmiInstantiateModel made no instance (GUID {md.guid}): "
                             f"{owner.last_message() or 'it logged no message'}")
        slave.component = component
        self._ident = ident
        return slave

    def bind(self, dll, comp, owner) -> None:
        """The FMU's <modelIdentifier>_fmi* functions, raw with FMI 1.0's
        argument types, and the calls of the wrapper's algorithm on the
        instance `comp`."""
        prefix = f"{self._ident}_fmi"

        def fn(name, *argtypes):
            f = getattr(dll, prefix + name)
            f.argtypes = list(argtypes)
            f.restype = c_int
            return f

        c = c_void_p
        vrs, reals, chars = POINTER(c_uint), POINTER(c_double), POINTER(c_char)
        f = self.functions = {
            "setTime": fn("SetTime", c, c_double),
            "setStates": fn("SetContinuousStates", c, reals, c_size_t),
            "getDerivatives": fn("GetDerivatives", c, reals, c_size_t),
            "getIndicators": fn("GetEventIndicators", c, reals, c_size_t),
            "getStates": fn("GetContinuousStates", c, reals, c_size_t),
            "getNominals": fn("GetNominalContinuousStates", c, reals, c_size_t),
            "completedStep": fn("CompletedIntegratorStep", c, chars),
            "enterEventMode": NO_MODE,
            "update": fn("EventUpdate", c, c_char, POINTER(EventInfo1)),
            "enterContinuousMode": NO_MODE,
            "getReal": fn("GetReal", c, vrs, c_size_t, reals),
            "setReal": fn("SetReal", c, vrs, c_size_t, reals),
            "getState": NO_GET_STATE,
            "setState": NO_SET_STATE,
        }
        self.get_real, self.set_real = f["getReal"], f["setReal"]
        self.set_inputs = lambda vr, n, v: f["setReal"](comp, vr, n, v)
        self.get_integer = fn("GetInteger", c, vrs, c_size_t, POINTER(c_int))
        self.set_integer = fn("SetInteger", c, vrs, c_size_t, POINTER(c_int))
        self._booleans = (fn("GetBoolean", c, vrs, c_size_t, chars), fn("SetBoolean", c, vrs, c_size_t, chars))
        self.get_boolean = _booleans_out(self._booleans[0])
        self.set_boolean = _booleans_in(self._booleans[1])
        self.get_string = fn("GetString", c, vrs, c_size_t, POINTER(c_char_p))
        self.set_string = fn("SetString", c, vrs, c_size_t, POINTER(c_char_p))
        self.free_state = lambda comp_, state: OK  # no state was ever made
        self.reset = lambda comp_: ERROR
        terminate = fn("Terminate", c)
        initialize = fn("Initialize", c, c_char, c_double, POINTER(EventInfo1))
        set_time = f["setTime"]
        tolerance = [FALSE, 0.0]
        initialized = [False]

        def setup(comp_, tol_defined, tol, start, stop_defined, stop):
            tolerance[:] = [TRUE if tol_defined else FALSE, float(tol) if tol_defined else 0.0]
            return set_time(comp_, start)  # the start time, before fmiInitialize

        info = EventInfo1()
        pending = []  # fmiInitialize's eventInfo, the answer to the wrapper's first update

        def exit_init(comp_):
            st = initialize(comp_, tolerance[0], tolerance[1], byref(info))
            if st <= 1:
                initialized[0] = True
                pending[:] = [st]
            return st

        self.setup = setup
        self.enter_init = lambda comp_: OK  # fmiInitialize does it all, at exit_init
        self.exit_init = exit_init
        self.terminate = lambda comp_: terminate(comp_) if initialized[0] else OK
        update = f["update"]

        def update_call():
            st = pending.pop() if pending else update(comp, FALSE, byref(info))
            changed = _flag(info.stateValueReferencesChanged)
            return (st, not _flag(info.iterationConverged), _flag(info.terminateSimulation), changed,
                    changed or _flag(info.stateValuesChanged), _flag(info.upcomingTimeEvent), info.nextEventTime)

        call_update = c_char()
        completed = f["completedStep"]

        def completed_call():
            st = completed(comp, byref(call_update))
            return st, _flag(call_update.value), False

        self.update, self.completed_step = update_call, completed_call
        self._terminate_call = self.terminate
        self._initialized = initialized

    def core_value_calls(self, variable):
        """The compiled core's get and set of an Integer, Enumeration or
        Boolean variable (fmiBoolean: a char), in a Model Exchange group
        (fmi/me_values.py), or None for another type."""
        if variable.type not in ("Integer", "Enumeration", "Boolean"):
            return None
        if variable.type == "Boolean":
            return value_calls(*self._booleans, 1, False, True)
        return value_calls(self.get_integer, self.set_integer, 4, False, False)

    def free(self, slave, comp) -> None:
        """fmiTerminate after a successful fmiInitialize, then fmiFreeModelInstance."""
        if getattr(self, "_initialized", [False])[0]:
            self._terminate_call(comp)
        fn = slave.dll[f"{self._ident}_fmiFreeModelInstance"]
        fn.argtypes, fn.restype = [c_void_p], None
        fn(comp)


def _booleans_out(get):
    def call(comp, vr, n, out):
        got = (c_char * max(1, n))()
        st = get(comp, vr, n, got)
        for k in range(n):
            out[k] = int(got[k] != FALSE)
        return st
    return call


def _booleans_in(set_):
    def call(comp, vr, n, values):
        return set_(comp, vr, n, (c_char * max(1, n))(*[TRUE if values[k] else FALSE for k in range(n)]))
    return call
