"""The FMI 3.0 Model Exchange face: an FMI 3.0 FMU's Model Exchange
functions, for the engine's wrapper (``engine/model_exchange.py``), which
composes it with an integrator and implements the instance contract.

As ``me2.ModelExchange2``, in FMI 3.0's calls: fmi3InstantiateModelExchange
with a logger that takes the FMU's strings as addresses, Float64 for the
reals, fmi3UpdateDiscreteStates and fmi3CompletedIntegratorStep in their
own shapes, the experiment's start and tolerance given when
Initialization Mode is entered, and values of every type through
``values3.Values3``.
"""

from __future__ import annotations

import ctypes
from ctypes import POINTER, byref, c_bool, c_double, c_int, c_size_t, c_uint, c_void_p

from fmpy.fmi3 import FMU3Model, fmi3LogMessageCallback

from ..errors import SceneError
from .archive import extract
from .calls import OK, declared, read_string
from .cs3 import LOG_MESSAGE
from .description import type_name
from .me_values import value_calls
from .values3 import Values3


class ModelExchange3:
    """The fmi3 Model Exchange functions of one instance (see the module's docstring)."""

    CORE_CALLS_TABLE = "cwme_calls_fmi3"  # cw_me.c's table of this version's calls whose shape differs
    CALL_NAMES = {"doStep": "the Model Exchange step", "getReal": "fmi3GetFloat64", "setReal": "fmi3SetFloat64",
                  "getInteger": "fmi3GetInt32", "getBoolean": "fmi3GetBoolean", "getString": "fmi3GetString",
                  "setValues": "fmi3Set*", "setInputDerivatives": "input derivatives of the Model Exchange wrapper",
                  "getOutputDerivatives": "output derivatives of the Model Exchange wrapper",
                  "getState": "fmi3GetFMUState", "setState": "fmi3SetFMUState", "reset": "fmi3Reset",
                  "setup": "fmi3EnterInitializationMode", "enterInit": "fmi3EnterInitializationMode",
                  "exitInit": "fmi3ExitInitializationMode", "instantiate": "fmi3InstantiateModelExchange"}
    NAMES = {"setTime": "fmi3SetTime", "setStates": "fmi3SetContinuousStates",
             "getDerivatives": "fmi3GetContinuousStateDerivatives", "getIndicators": "fmi3GetEventIndicators",
             "completedStep": "fmi3CompletedIntegratorStep", "enterEventMode": "fmi3EnterEventMode",
             "update": "fmi3UpdateDiscreteStates", "enterContinuousMode": "fmi3EnterContinuousTimeMode",
             "getStates": "fmi3GetContinuousStates", "getNominals": "fmi3GetNominalsOfContinuousStates",
             "setReal": "fmi3SetFloat64"}
    values: Values3 | None = None  # values of every FMI 3.0 type (set by bind)

    def instantiate(self, owner):
        """Load and instantiate the FMU for `owner` (the wrapper: its name,
        messages, crash guard); returns fmpy's model object."""
        md = owner.md
        unzip = extract(owner.path)
        try:
            slave = FMU3Model(guid=md.guid, unzipDirectory=str(unzip),
                              modelIdentifier=md.modelExchange.modelIdentifier, instanceName=owner.name)
        except Exception as e:
            raise SceneError(f"{owner.path}: cannot load the FMU's binary for this platform: {e}") from None
        messages = owner.messages

        def logger(env, status, category, message):
            # Addresses, read without trusting them; env is not used.
            messages.append((status, read_string(message)))
            del messages[:-50]

        owner._guard(slave.dll, ("fmi3InstantiateModelExchange", "fmi3GetVersion"))
        try:
            # As fmpy's instantiate, with a logger that takes the strings as addresses.
            self._log_callback = LOG_MESSAGE(logger)  # kept from GC
            slave.logMessage = ctypes.cast(self._log_callback, fmi3LogMessageCallback)
            slave.component = slave.fmi3InstantiateModelExchange(
                owner.name.encode(), md.guid.encode(), (str(unzip / "resources") + "/").encode(),
                False, False, None, slave.logMessage)
            if not slave.component:
                raise Exception("Failed to instantiate FMU")
        except Exception as e:
            owner.check_crash("fmi3InstantiateModelExchange")
            raise SceneError(
                f"{owner.path}: fmi3InstantiateModelExchange refused the model description's instantiation "
                f"token {md.guid}: {owner.last_message() or e}") from None
        return slave

    def bind(self, dll, comp, owner) -> None:
        """The FMU's fmi3 functions, raw with their argument types, and the
        calls of the wrapper's algorithm on the instance `comp`; `owner`'s
        values of every type through Values3."""

        def fn(name, *argtypes):
            return declared(dll, name, argtypes)

        inst = c_void_p
        vrs, reals, pb = POINTER(c_uint), POINTER(c_double), POINTER(c_bool)
        get_f64 = fn("fmi3GetFloat64", inst, vrs, c_size_t, reals, c_size_t)
        set_f64 = fn("fmi3SetFloat64", inst, vrs, c_size_t, reals, c_size_t)
        f = self.functions = {
            "setTime": fn("fmi3SetTime", inst, c_double),
            "setStates": fn("fmi3SetContinuousStates", inst, reals, c_size_t),
            "getDerivatives": fn("fmi3GetContinuousStateDerivatives", inst, reals, c_size_t),
            "getIndicators": fn("fmi3GetEventIndicators", inst, reals, c_size_t),
            "getStates": fn("fmi3GetContinuousStates", inst, reals, c_size_t),
            "getNominals": fn("fmi3GetNominalsOfContinuousStates", inst, reals, c_size_t),
            "completedStep": fn("fmi3CompletedIntegratorStep", inst, c_bool, pb, pb),
            "enterEventMode": fn("fmi3EnterEventMode", inst),
            "update": fn("fmi3UpdateDiscreteStates", inst, pb, pb, pb, pb, pb, reals),
            "enterContinuousMode": fn("fmi3EnterContinuousTimeMode", inst),
            "getReal": get_f64,
            "setReal": set_f64,
            "getState": fn("fmi3GetFMUState", inst, POINTER(c_void_p)),
            "setState": fn("fmi3SetFMUState", inst, c_void_p),
        }
        self.get_real = lambda c, vr, n, out: get_f64(c, vr, n, out, n)
        self.set_real = lambda c, vr, n, val: set_f64(c, vr, n, val, n)
        self.set_inputs = lambda vr, n, v: set_f64(comp, vr, n, v, n)
        get_i32 = fn("fmi3GetInt32", inst, vrs, c_size_t, POINTER(c_int), c_size_t)
        self.get_integer = lambda c, vr, n, out: get_i32(c, vr, n, out, n)
        self.set_integer = self.get_boolean = self.set_boolean = self.get_string = self.set_string = None
        self.free_state = fn("fmi3FreeFMUState", inst, POINTER(c_void_p))
        self.reset = fn("fmi3Reset", inst)
        self.terminate = fn("fmi3Terminate", inst)
        enter_init = fn("fmi3EnterInitializationMode", inst, c_bool, c_double, c_double, c_bool, c_double)
        self.exit_init = fn("fmi3ExitInitializationMode", inst)
        args = [(0, 0.0, 0.0, 0, 0.0)]

        def setup(c, tol_defined, tol, start, stop_defined, stop):
            args[0] = (tol_defined, tol, start, stop_defined, stop)
            return OK  # FMI 3.0 takes these when initialization mode is entered

        self.setup = setup
        self.enter_init = lambda c: enter_init(c, *args[0])
        update = f["update"]
        flags = [c_bool() for _ in range(5)]
        next_time = c_double()

        def update_call():
            st = update(comp, *(byref(b) for b in flags), byref(next_time))
            need, term, nominals, values, defined = (b.value for b in flags)
            return st, need, term, nominals, values, defined, next_time.value

        completed = f["completedStep"]
        enter, term = c_bool(), c_bool()

        def completed_call():
            st = completed(comp, False, byref(enter), byref(term))
            return st, enter.value, term.value

        self.update, self.completed_step = update_call, completed_call
        self.values = Values3(owner, dll)

    # The bytes of a value of each discrete type the compiled group sets (fmi3Boolean: a bool).
    _VALUE_BYTES = {"Int32": 4, "Int64": 8, "Enumeration": 8, "Boolean": 1}

    def core_value_calls(self, variable):
        """The compiled core's fmi3Get and fmi3Set of an Int32, Int64,
        Enumeration or Boolean variable, in a Model Exchange group
        (fmi/me_values.py), or None for another type."""
        values = self.values
        kind = type_name(values.owner.md, variable)
        size = self._VALUE_BYTES.get(kind)
        if size is None:
            return None
        return value_calls(*values._value_functions(kind), size, True, kind == "Boolean")

    @staticmethod
    def free(slave, comp) -> None:
        slave.fmi3FreeInstance(comp)
