"""The FMI 2.0 Co-Simulation face: an instance of an FMI 2.0 FMU's
Co-Simulation interface behind the instance contract (``contract.py``).

Loading goes through fmpy (``FMU2Slave``); the per-step hot path calls the
FMU's own fmi2 C symbols with preallocated ctypes arrays, so that a
communication step costs a few ctypes calls and no Python-side allocation;
the compiled core calls the same symbols (``core_calls``).
"""

from __future__ import annotations

import ctypes
import weakref
from ctypes import POINTER, byref, c_char_p, c_double, c_int, c_size_t, c_uint, c_void_p

from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.fmi2 import fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE
from fmpy import calloc, free

from ..errors import SceneError
from .archive import extract
from .calls import LAST_SUCCESSFUL_TIME, TERMINATED, WARNING, _SINK, declared, formatting_logger, new_slave
from .contract import Instance

# The FMI 2.0 functions the compiled core's port calls (contract.CORE_CALLS).
_CORE_SYMBOLS = ("fmi2DoStep", "fmi2GetReal", "fmi2SetReal", "fmi2SetRealInputDerivatives",
                 "fmi2GetRealOutputDerivatives", "fmi2GetFMUstate", "fmi2SetFMUstate")


def fmi2_callbacks(name: str, messages: list, owner) -> tuple:
    """fmi2CallbackFunctions whose logger keeps the FMU's messages in
    `messages` (the last 50), with the objects to keep alive and the
    finalizer that forgets the environment (None without the core's
    formatting logger); `owner`: the object whose life the environment
    follows."""

    def keep(status, message):
        messages.append((status, message.decode("utf-8", "replace") if message else ""))
        del messages[:-50]

    callbacks = fmi2CallbackFunctions()
    core = formatting_logger()
    alive, forget = None, None
    if core is not None:
        # cw_logger formats and hands the text to this instance's sink,
        # which it finds in the core's registry of live environments by
        # the componentEnvironment (or, when the FMU passes another, by
        # the instance name): an environment is only ever looked up.
        alive = _SINK(lambda instance, status, category, text: keep(status, text))
        env = ctypes.cast(alive, c_void_p).value
        callbacks.logger = core[0]
        callbacks.componentEnvironment = env
        core[1].cw_env_register(env, name.encode("utf-8", "replace"), alive)
        # Forgotten when freed (free() calls it), or when its owner goes.
        forget = weakref.finalize(owner, core[1].cw_env_unregister, env)
    else:
        alive = callbacks.logger = fmi2CallbackLoggerTYPE(
            lambda env, instance, status, category, message: keep(status, message))
    # libc's own calloc and free, cast rather than wrapped: a wrapper
    # would be a Python callback on every allocation inside the FMU.
    callbacks.allocateMemory = ctypes.cast(calloc, fmi2CallbackAllocateMemoryTYPE)
    callbacks.freeMemory = ctypes.cast(free, fmi2CallbackFreeMemoryTYPE)
    return callbacks, alive, forget


class Instance2(Instance):
    """An instantiated FMI 2.0 Co-Simulation FMU with fast access to its fmi2 functions."""

    CALL_NAMES = {"doStep": "fmi2DoStep", "getReal": "fmi2GetReal", "setReal": "fmi2SetReal",
                  "getInteger": "fmi2GetInteger", "getBoolean": "fmi2GetBoolean", "getString": "fmi2GetString",
                  "setValues": "fmi2Set*", "setInputDerivatives": "fmi2SetRealInputDerivatives",
                  "getOutputDerivatives": "fmi2GetRealOutputDerivatives", "getState": "fmi2GetFMUstate",
                  "setState": "fmi2SetFMUstate", "reset": "fmi2Reset", "setup": "fmi2SetupExperiment",
                  "enterInit": "fmi2EnterInitializationMode", "exitInit": "fmi2ExitInitializationMode",
                  "instantiate": "fmi2Instantiate"}

    # -- loading -------------------------------------------------------

    def instantiate(self) -> None:
        unzip = extract(self.path)
        try:
            self._slave = new_slave(FMU2Slave, unzip, self.md, self.name, self.md.coSimulation.modelIdentifier)
        except Exception as e:  # fmpy raises a bare Exception for a bad library
            raise SceneError(f"{self.shown}: cannot load the FMU's binary for this platform: {e}") from None
        self._guard(self._slave.dll, ("fmi2Instantiate",))
        self._callbacks, self._sink, forget = fmi2_callbacks(self.name, self.messages, self)
        if forget is not None:
            self._forget_env = forget
        try:
            self._slave.instantiate(callbacks=self._callbacks)
        except Exception as e:
            self._forget()
            self.check_crash("fmi2Instantiate")
            # The binary refused its own model description (another build or
            # another model): the FMU file is broken, which is bad input.
            raise SceneError(
                f"{self.shown}: fmi2Instantiate refused the model description's GUID "
                f"{self.md.guid}: {self.last_message() or e}") from None
        self.component = self._slave.component
        self._bind(self._slave.dll)

    def _bind(self, dll) -> None:
        """Raw C symbols with argtypes, bypassing fmpy's per-call wrappers."""

        def fn(name, *argtypes):
            return declared(dll, name, argtypes)

        comp = c_void_p
        self.c_doStep = fn("fmi2DoStep", comp, c_double, c_double, c_int)
        self.c_getReal = fn("fmi2GetReal", comp, POINTER(c_uint), c_size_t, POINTER(c_double))
        self.c_setReal = fn("fmi2SetReal", comp, POINTER(c_uint), c_size_t, POINTER(c_double))
        self.c_getInteger = fn("fmi2GetInteger", comp, POINTER(c_uint), c_size_t, POINTER(c_int))
        self.c_setInteger = fn("fmi2SetInteger", comp, POINTER(c_uint), c_size_t, POINTER(c_int))
        self.c_setBoolean = fn("fmi2SetBoolean", comp, POINTER(c_uint), c_size_t, POINTER(c_int))
        self.c_getBoolean = fn("fmi2GetBoolean", comp, POINTER(c_uint), c_size_t, POINTER(c_int))
        self.c_getString = fn("fmi2GetString", comp, POINTER(c_uint), c_size_t, POINTER(c_char_p))
        self.c_setString = fn("fmi2SetString", comp, POINTER(c_uint), c_size_t, POINTER(c_char_p))
        self.c_getBooleanStatus = fn("fmi2GetBooleanStatus", comp, c_int, POINTER(c_int))
        self.c_getRealStatus = fn("fmi2GetRealStatus", comp, c_int, POINTER(c_double))
        self.c_setInputDerivatives = fn(
            "fmi2SetRealInputDerivatives", comp, POINTER(c_uint), c_size_t, POINTER(c_int), POINTER(c_double)
        )
        self.c_getOutputDerivatives = fn(
            "fmi2GetRealOutputDerivatives", comp, POINTER(c_uint), c_size_t, POINTER(c_int), POINTER(c_double)
        )
        self.c_getState = fn("fmi2GetFMUstate", comp, POINTER(c_void_p))
        self.c_setState = fn("fmi2SetFMUstate", comp, c_void_p)
        self.c_freeState = fn("fmi2FreeFMUstate", comp, POINTER(c_void_p))
        self.c_reset = fn("fmi2Reset", comp)
        self.c_setup = fn("fmi2SetupExperiment", comp, c_int, c_double, c_double, c_int, c_double)
        self.c_enterInit = fn("fmi2EnterInitializationMode", comp)
        self.c_exitInit = fn("fmi2ExitInitializationMode", comp)
        self.c_terminate = fn("fmi2Terminate", comp)

    def core_calls(self, lib) -> tuple[int, tuple[int, ...]]:
        """The FMU's own fmi2 symbols: the core calls them as they are."""
        dll = self._slave.dll
        return self.component, tuple(ctypes.cast(getattr(dll, name), c_void_p).value for name in _CORE_SYMBOLS)

    def _free_instance(self) -> None:
        self._slave.fmi2FreeInstance(self.component)

    # -- what the FMU says of a discarded step -----------------------------------

    def terminated(self) -> bool:
        """fmi2GetBooleanStatus(fmi2Terminated): the FMU wants the simulation
        to end (asked after a discarded step; an FMU that cannot say, says no)."""
        value = c_int(0)
        keep = len(self.messages)
        if self.c_getBooleanStatus(self.component, TERMINATED, byref(value)) > WARNING:
            del self.messages[keep:]  # not providing the status is no error
            return False
        return bool(value.value)

    def last_successful_time(self) -> float | None:
        """fmi2GetRealStatus(fmi2LastSuccessfulTime), s, or None."""
        value = c_double(0.0)
        keep = len(self.messages)
        if self.c_getRealStatus(self.component, LAST_SUCCESSFUL_TIME, byref(value)) > WARNING:
            del self.messages[keep:]
            return None
        return value.value
