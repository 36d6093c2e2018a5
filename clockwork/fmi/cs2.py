"""One FMU instance as the master sees it.

Loading goes through fmpy (``FMU2Slave``); the per-step hot path calls the
FMU's own C symbols with preallocated ctypes arrays, so that a
communication step costs a few ctypes calls and no Python-side allocation.
"""

from __future__ import annotations

import ctypes
import weakref
from ctypes import POINTER, byref, c_char_p, c_double, c_int, c_size_t, c_uint, c_void_p
from pathlib import Path

from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.fmi2 import fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE
from fmpy import calloc, free

from ..errors import ParametersRefused, SceneError, SimulationError, UsageError
from .description import (default_tolerance, default_tolerance_problem, outputs_after_inputs,
                          read_fmu)

from .archive import extract
from .calls import (DISCARD, FATAL, LAST_SUCCESSFUL_TIME, NO_MESSAGE, STATUS_NAMES, TERMINATED, WARNING, _SINK,
                    crash_of, crashes, declared, formatting_logger, guard_library, new_slave, unattributed)
from .variables import instance_variables


class Instance:
    """An instantiated FMU with fast access to its fmi2 functions."""

    fmi_version = 2  # fmu3.Instance3 says 3, fmu1.Instance1 1
    do_step_name = "fmi2DoStep"  # in messages
    _fmpy_class = FMU2Slave  # model_exchange.MEInstance: FMU2Model
    # Instances freed in this process: a master looks for a freed instance
    # of its own before a run only when this changed (systems have thousands).
    frees = 0
    # Its binary under the core's crash handler (guard_library's address, or
    # None), and the crashes of that binary before this instance was made.
    _guarded: int | None = None
    _crashes_seen = 0

    def _guard(self, dll, names: tuple[str, ...]) -> None:
        """Put this instance's binary under the crash handler (`names`: the
        functions that may name the library, the first it has)."""
        self._guarded = guard_library(dll, names, self.name)
        self._crashes_seen = crashes(self._guarded)  # an earlier instance's crash is not this one's

    def _interface(self):
        """The modelDescription element of the interface it runs through."""
        return self.md.coSimulation
    arrays: dict[str, tuple[int, int]] = {}  # FMI 3.0 array variables: name -> (vr, values) (fmu3.Instance3)
    elements: dict[str, list[str]] = {}  # FMI 3.0 array variables: name -> its element names, row-major
    # What messages call the FMU where its path is a copy (an SSP archive's
    # member, "x.ssp/resources/m.fmu"); None: its path.
    label: str | None = None

    @property
    def shown(self) -> str:
        return self.label or str(self.path)

    def __reduce_ex__(self, protocol):
        raise UsageError(f"the FMU instance {self.name} cannot be pickled or copied: it is a loaded library "
                         "and its C state")

    def __init__(self, name: str, path: Path, model_description=None):
        self.name = name
        self.path = Path(path)
        described = read_fmu(self.path, need_binary=False)
        self.md = model_description or described[0]
        self.model_name = self.md.modelName
        self.variables = instance_variables(self.md)
        self._read_capabilities()
        self.outputs_after_inputs = self._outputs_after_inputs()
        self.default_tolerance = default_tolerance(self.md)
        self.event_indicators = list(described[2])
        self.messages: list[tuple[int, str]] = []
        self._slave = None
        self._state = c_void_p()

    def _outputs_after_inputs(self) -> bool:
        """Whether the master may read outputs after setting inputs with no
        step between (engine/wiring.py): FMI 2.0 (4.2.4) and FMI 3.0's Step
        Mode forbid it unless the description says so in clockwork's
        annotation (description.declares_outputs_after_inputs)."""
        return outputs_after_inputs(self.path)

    def _read_capabilities(self) -> None:
        """What the FMU's <CoSimulation> element declares (a Model Exchange wrapper says its own)."""
        cs = self.md.coSimulation
        self.max_output_derivative_order = int(cs.maxOutputDerivativeOrder or 0)
        self.can_interpolate_inputs = bool(cs.canInterpolateInputs)
        self.can_get_set_state = bool(cs.canGetAndSetFMUstate)

    # -- loading -------------------------------------------------------

    def instantiate(self) -> None:
        unzip = extract(self.path)
        try:
            self._slave = new_slave(self._fmpy_class, unzip, self.md, self.name, self._interface().modelIdentifier)
        except Exception as e:  # fmpy raises a bare Exception for a bad library
            raise SceneError(f"{self.shown}: cannot load the FMU's binary for this platform: {e}") from None
        messages = self.messages

        def keep(status, message):
            messages.append((status, message.decode("utf-8", "replace") if message else ""))
            del messages[:-50]

        self._guard(self._slave.dll, ("fmi2Instantiate",))
        self._callbacks = fmi2CallbackFunctions()
        core = formatting_logger()
        if core is not None:
            # cw_logger formats and hands the text to this instance's sink,
            # which it finds in the core's registry of live environments by
            # the componentEnvironment (or, when the FMU passes another, by
            # the instance name): an environment is only ever looked up.
            self._sink = _SINK(lambda instance, status, category, text: keep(status, text))
            env = ctypes.cast(self._sink, c_void_p).value
            self._callbacks.logger = core[0]
            self._callbacks.componentEnvironment = env
            core[1].cw_env_register(env, self.name.encode("utf-8", "replace"), self._sink)
            # Forgotten when freed (free() calls it), or when this object goes.
            self._forget_env = weakref.finalize(self, core[1].cw_env_unregister, env)
        else:
            self._callbacks.logger = fmi2CallbackLoggerTYPE(
                lambda env, instance, status, category, message: keep(status, message))
        # libc's own calloc and free, cast rather than wrapped: a wrapper
        # would be a Python callback on every allocation inside the FMU.
        self._callbacks.allocateMemory = ctypes.cast(calloc, fmi2CallbackAllocateMemoryTYPE)
        self._callbacks.freeMemory = ctypes.cast(free, fmi2CallbackFreeMemoryTYPE)
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
        dll = self._slave.dll
        self._bind(dll)

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

    @property
    def freed(self) -> bool:
        """Whether free() ran (an instance never instantiated is not freed)."""
        return self._slave is None and hasattr(self, "component")

    def crash(self) -> str | None:
        """What crashed this instance's FMU binary in this process (its call
        and the signal), or None: such an FMU is not called again."""
        return crash_of(self._guarded, self._crashes_seen)

    def check_crash(self, what: str) -> None:
        """Raise the failed run when the FMU crashed (a failed instantiate)."""
        if self.crash() is not None:
            raise self.fail(what, FATAL)

    def free(self) -> None:
        if self._slave is None:
            return
        if self.crash() is not None:  # its code and state are not to be trusted again: left as it is
            self._slave = None
            self._forget()
            Instance.frees += 1
            return
        if self._state.value:
            self.c_freeState(self.component, byref(self._state))
        try:
            self._free_instance()
        finally:
            self._slave = None
            self._forget()
            Instance.frees += 1

    def _forget(self) -> None:
        """Take this instance's logger environment out of the core's registry."""
        forget = getattr(self, "_forget_env", None)
        if forget is not None:
            forget()

    def _free_instance(self) -> None:
        self._slave.fmi2FreeInstance(self.component)

    # -- status handling ------------------------------------------------

    def last_message(self) -> str:
        """The FMU's last message that reports a failure (status Discard or
        worse): an earlier warning or remark does not explain a failure."""
        for status, text in reversed(self.messages):
            if status >= DISCARD and text:
                return text
        for _, status, text in reversed(unattributed):  # logged through a bad environment and name
            if status >= DISCARD and text:
                return f"{text} (logged through no live instance's environment or name)"
        return ""

    def fail(self, what: str, status: int, time: float | None = None,
             error: type[SimulationError] = SimulationError) -> SimulationError:
        crash = self.crash()
        if crash is not None:
            return error(f"{self.model_name}: {what} crashed the FMU in {crash}; the call was abandoned",
                         time=time, instance=self.name)
        name = STATUS_NAMES[status] if 0 <= status < len(STATUS_NAMES) else f"status {status}"
        text = f"{self.model_name}: {what} returned {name}: {self.last_message() or NO_MESSAGE}"
        return error(text, time=time, instance=self.name)

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

    def check(self, status: int, what: str, time: float | None = None,
              error: type[SimulationError] = SimulationError) -> None:
        if status > WARNING:
            raise self.fail(what, status, time, error)

    # -- setup ----------------------------------------------------------

    def setup(self, start: float, parameters: dict[str, object], tolerance: float | None = None) -> None:
        """fmi2SetupExperiment (with the relative tolerance when one is
        given: the scene's, else the FMU's DefaultExperiment's), parameters,
        initialization mode."""
        if tolerance is None:
            tolerance = self.default_tolerance
            problem = default_tolerance_problem(self.md)
            if problem:  # the scene layer refuses it first
                raise SceneError(f"{self.shown}: modelDescription.xml: DefaultExperiment tolerance = {tolerance:g}: "
                                 f"{problem}; or give master.tolerance")
        defined = tolerance is not None
        self.check(self.c_setup(self.component, int(defined), float(tolerance) if defined else 0.0, start, 0, 0.0),
                   "fmi2SetupExperiment")
        self.set_values(parameters, "setting parameters", ParametersRefused)
        self.check(self.c_enterInit(self.component), "fmi2EnterInitializationMode")

    def set_values(self, values: dict[str, object], what: str = "fmi2Set*",
                   error: type[SimulationError] = SimulationError) -> None:
        for name, value in values.items():
            v = self.variables[name]
            vr = (c_uint * 1)(v.vr)
            if v.type == "Real":
                st = self.c_setReal(self.component, vr, 1, (c_double * 1)(float(value)))
            elif v.type in ("Integer", "Enumeration"):
                st = self.c_setInteger(self.component, vr, 1, (c_int * 1)(int(value)))
            elif v.type == "Boolean":
                st = self.c_setBoolean(self.component, vr, 1, (c_int * 1)(1 if value else 0))
            elif v.type == "String":
                st = self.c_setString(self.component, vr, 1, (c_char_p * 1)(str(value).encode("utf-8")))
            else:
                raise SimulationError(f"{self.name}.{name}: type {v.type} is not supported")
            self.check(st, f"{what} ({name} = {value!r})", error=error)

    def exit_init(self) -> None:
        self.check(self.c_exitInit(self.component), "fmi2ExitInitializationMode", error=ParametersRefused)

    def reset(self) -> None:
        """fmi2Reset: back to the state right after instantiation."""
        self.check(self.c_reset(self.component), "fmi2Reset")
        del self.messages[:]  # an error after the reset must not quote one from before

    # -- convenience getters (not on the hot path) ----------------------

    def get_real(self, names: list[str]) -> list[float]:
        vrs = (c_uint * len(names))(*[self.variables[n].vr for n in names])
        out = (c_double * len(names))()
        self.check(self.c_getReal(self.component, vrs, len(names), out), "fmi2GetReal")
        return list(out)

    def get_integer(self, names: list[str]) -> list[int]:
        vrs = (c_uint * len(names))(*[self.variables[n].vr for n in names])
        out = (c_int * len(names))()
        self.check(self.c_getInteger(self.component, vrs, len(names), out), "fmi2GetInteger")
        return list(out)

    def get_string(self, names: list[str]) -> list[str]:
        vrs = (c_uint * len(names))(*[self.variables[n].vr for n in names])
        out = (c_char_p * len(names))()
        self.check(self.c_getString(self.component, vrs, len(names), out), "fmi2GetString")
        return [(x or b"").decode("utf-8", "replace") for x in out]

    def get_values(self, names: list[str]) -> list:
        """Values of any type, each through the fmi2Get* of its type
        (Enumeration through fmi2GetInteger); not on the hot path."""
        getters = {"Real": self.get_real, "Integer": self.get_integer, "Enumeration": self.get_integer,
                   "Boolean": self.get_boolean, "String": self.get_string}
        return [getters[self.variables[n].type]([n])[0] for n in names]

    def get_boolean(self, names: list[str]) -> list[bool]:
        vrs = (c_uint * len(names))(*[self.variables[n].vr for n in names])
        out = (c_int * len(names))()
        self.check(self.c_getBoolean(self.component, vrs, len(names), out), "fmi2GetBoolean")
        return [bool(x) for x in out]

    def output_derivatives(self, names: list[str], order: int) -> list[float] | None:
        """Derivatives of outputs, or None when the FMU does not offer them."""
        if order > self.max_output_derivative_order:
            return None
        n = len(names)
        vrs = (c_uint * n)(*[self.variables[x].vr for x in names])
        orders = (c_int * n)(*([order] * n))
        out = (c_double * n)()
        keep = len(self.messages)
        if self.c_getOutputDerivatives(self.component, vrs, n, orders, out) > WARNING:
            del self.messages[keep:]  # an unsupported derivative is not an error
            return None
        return list(out)

    # -- FMU state ------------------------------------------------------

    def save_state(self, t: float | None = None) -> None:
        """Overwrite this instance's one saved state (no allocation growth); t (s) names the point in errors."""
        self.check(self.c_getState(self.component, byref(self._state)), "fmi2GetFMUstate", t)

    def restore_state(self, t: float | None = None) -> None:
        self.check(self.c_setState(self.component, self._state), "fmi2SetFMUstate", t)
