"""The FMI 2.0 Model Exchange face: an FMI 2.0 FMU's Model Exchange
functions, for the engine's wrapper (``engine/model_exchange.py``), which
composes it with an integrator and implements the instance contract.

The face loads and instantiates the FMU (fmpy's ``FMU2Model``, the same
logger and memory callbacks as the Co-Simulation face), binds the FMU's
own fmi2 symbols with their argument types, and hands them over in the
shape the wrapper's algorithm calls (``set_time(t)``, ``update()``...);
what the wrapper stores in its struct for the compiled core's twin
(cw_me.c) is ``functions``. It knows nothing of integration.
"""

from __future__ import annotations

from ctypes import POINTER, byref, c_char_p, c_double, c_int, c_size_t, c_uint, c_void_p

from fmpy.fmi2 import FMU2Model, fmi2EventInfo

from ..errors import SceneError
from .archive import extract
from .cs2 import fmi2_callbacks
from .calls import declared, new_slave
from .me_values import value_calls


class ModelExchange2:
    """The fmi2 Model Exchange functions of one instance (see the module's docstring)."""

    CORE_CALLS_TABLE = "cwme_calls_fmi2"  # cw_me.c's table of this version's calls whose shape differs
    # The contract's calls, named as the wrapper does them (contract.Instance.named).
    CALL_NAMES = {"doStep": "the Model Exchange step", "getReal": "fmi2GetReal", "setReal": "fmi2SetReal",
                  "getInteger": "fmi2GetInteger", "getBoolean": "fmi2GetBoolean", "getString": "fmi2GetString",
                  "setValues": "fmi2Set*", "setInputDerivatives": "input derivatives of the Model Exchange wrapper",
                  "getOutputDerivatives": "output derivatives of the Model Exchange wrapper",
                  "getState": "fmi2GetFMUstate", "setState": "fmi2SetFMUstate", "reset": "fmi2Reset",
                  "setup": "fmi2SetupExperiment", "enterInit": "fmi2EnterInitializationMode",
                  "exitInit": "fmi2ExitInitializationMode", "instantiate": "fmi2Instantiate"}
    # The FMU functions of the wrapper's algorithm (me_step.FMU_CALLS), by their FMI 2.0 names.
    NAMES = {"setTime": "fmi2SetTime", "setStates": "fmi2SetContinuousStates",
             "getDerivatives": "fmi2GetDerivatives", "getIndicators": "fmi2GetEventIndicators",
             "completedStep": "fmi2CompletedIntegratorStep", "enterEventMode": "fmi2EnterEventMode",
             "update": "fmi2NewDiscreteStates", "enterContinuousMode": "fmi2EnterContinuousTimeMode",
             "getStates": "fmi2GetContinuousStates", "getNominals": "fmi2GetNominalsOfContinuousStates",
             "setReal": "fmi2SetReal"}
    values = None  # values of every type go through the contract's typed calls (get_integer...)

    def instantiate(self, owner):
        """Load and instantiate the FMU for `owner` (the wrapper: its name,
        messages, crash guard); returns fmpy's model object."""
        md = owner.md
        unzip = extract(owner.path)
        try:
            slave = new_slave(FMU2Model, unzip, md, owner.name, md.modelExchange.modelIdentifier)
        except Exception as e:  # fmpy raises a bare Exception for a bad library
            raise SceneError(f"{owner.shown}: cannot load the FMU's binary for this platform: {e}") from None
        owner._guard(slave.dll, ("fmi2Instantiate",))
        self._callbacks, self._sink, forget = fmi2_callbacks(owner.name, owner.messages, owner)
        if forget is not None:
            owner._forget_env = forget
        try:
            slave.instantiate(callbacks=self._callbacks)
        except Exception as e:
            owner._forget()
            owner.check_crash("fmi2Instantiate")
            raise SceneError(
                f"{owner.shown}: fmi2Instantiate refused the model description's GUID "
                f"{md.guid}: {owner.last_message() or e}") from None
        return slave

    def bind(self, dll, comp, owner) -> None:
        """The FMU's fmi2 functions, raw with their argument types, and the
        calls of the wrapper's algorithm on the instance `comp` (`owner`'s
        values of every type go through the contract's typed calls)."""

        def fn(name, *argtypes):
            return declared(dll, name, argtypes)

        c = c_void_p
        vrs, reals, ints = POINTER(c_uint), POINTER(c_double), POINTER(c_int)
        f = self.functions = {
            "setTime": fn("fmi2SetTime", c, c_double),
            "setStates": fn("fmi2SetContinuousStates", c, reals, c_size_t),
            "getDerivatives": fn("fmi2GetDerivatives", c, reals, c_size_t),
            "getIndicators": fn("fmi2GetEventIndicators", c, reals, c_size_t),
            "getStates": fn("fmi2GetContinuousStates", c, reals, c_size_t),
            "getNominals": fn("fmi2GetNominalsOfContinuousStates", c, reals, c_size_t),
            "completedStep": fn("fmi2CompletedIntegratorStep", c, c_int, ints, ints),
            "enterEventMode": fn("fmi2EnterEventMode", c),
            "update": fn("fmi2NewDiscreteStates", c, POINTER(fmi2EventInfo)),
            "enterContinuousMode": fn("fmi2EnterContinuousTimeMode", c),
            "getReal": fn("fmi2GetReal", c, vrs, c_size_t, reals),
            "setReal": fn("fmi2SetReal", c, vrs, c_size_t, reals),
            "getState": fn("fmi2GetFMUstate", c, POINTER(c_void_p)),
            "setState": fn("fmi2SetFMUstate", c, c_void_p),
        }
        self.get_real, self.set_real = f["getReal"], f["setReal"]
        self.set_inputs = lambda vr, n, v: f["setReal"](comp, vr, n, v)
        self.get_integer = fn("fmi2GetInteger", c, vrs, c_size_t, ints)
        self.set_integer = fn("fmi2SetInteger", c, vrs, c_size_t, ints)
        self.get_boolean = fn("fmi2GetBoolean", c, vrs, c_size_t, ints)
        self.set_boolean = fn("fmi2SetBoolean", c, vrs, c_size_t, ints)
        self.get_string = fn("fmi2GetString", c, vrs, c_size_t, POINTER(c_char_p))
        self.set_string = fn("fmi2SetString", c, vrs, c_size_t, POINTER(c_char_p))
        self.free_state = fn("fmi2FreeFMUstate", c, POINTER(c_void_p))
        self.reset = fn("fmi2Reset", c)
        self.terminate = fn("fmi2Terminate", c)
        self.setup = fn("fmi2SetupExperiment", c, c_int, c_double, c_double, c_int, c_double)
        self.enter_init = fn("fmi2EnterInitializationMode", c)
        self.exit_init = fn("fmi2ExitInitializationMode", c)
        info = fmi2EventInfo()
        update = f["update"]

        def update_call():
            st = update(comp, byref(info))
            return (st, bool(info.newDiscreteStatesNeeded), bool(info.terminateSimulation),
                    bool(info.nominalsOfContinuousStatesChanged), bool(info.valuesOfContinuousStatesChanged),
                    bool(info.nextEventTimeDefined), info.nextEventTime)

        enter, term = c_int(), c_int()
        completed = f["completedStep"]

        def completed_call():
            st = completed(comp, 0, byref(enter), byref(term))
            return st, bool(enter.value), bool(term.value)

        self.update, self.completed_step = update_call, completed_call

    def core_value_calls(self, variable):
        """The compiled core's get and set of an Integer, Enumeration or
        Boolean variable, in a Model Exchange group (fmi/me_values.py), or
        None for another type."""
        if variable.type not in ("Integer", "Enumeration", "Boolean"):
            return None
        if variable.type == "Boolean":
            return value_calls(self.get_boolean, self.set_boolean, 4, False, True)
        return value_calls(self.get_integer, self.set_integer, 4, False, False)

    @staticmethod
    def free(slave, comp) -> None:
        slave.fmi2FreeInstance(comp)
