"""The instance contract: what the master and the compiled core ask of an
FMU instance, whatever its FMI version and interface.

``Instance`` is the contract and the code every face shares; it is no
face itself. The faces implement it, one per FMI version and interface:
``cs1.Instance1``, ``cs2.Instance2`` and ``cs3.Instance3`` for
Co-Simulation, and the engine's Model Exchange wrapper
(``engine/model_exchange.py``), which composes an integrator with a
Model Exchange face (``me2.py``, ``me3.py``). ``engine/instances.py``
(the one factory) is the only place that reads the version and the
interface to choose one; the master (``engine/master.py`` and the modules
it uses) and the compiled core (src_c/master) never ask.

What the contract holds
-----------------------

Values in and out (the hot path). The ports call these with their
preallocated ctypes arrays, bound once at set-up (``Port.__init__``), so a
communication step adds no Python call of its own:

- ``component``: the first argument of every call below;
- ``c_getReal(comp, vr, n, out)``, ``c_setReal(comp, vr, n, values)``:
  n real values (FMI 3.0: Float64, an array element by its own code);
- ``c_setInputDerivatives(comp, vr, n, orders, values)``: the inputs'
  polynomials (their derivatives at the current time; FMI 3.0 keeps them
  for its intermediate update), where ``can_interpolate_inputs``;
- ``c_getOutputDerivatives(comp, vr, n, orders, out)``, up to
  ``max_output_derivative_order``;
- ``c_doStep(comp, t, h, no_set_prior)``: the step from t to t + h, s.
  Its outcome is a status: OK or Warning, the step is taken (an FMI 3.0
  early return at the FMU's own event is handled inside and the step goes
  on to t + h); Discard, the step is not taken; Error or Fatal, the run
  fails (``fail`` makes the error). "The FMU asks to end" is ``ended``:
  after a Discard (FMI 2.0's fmi2Terminated, an FMU's terminateSimulation
  in a step it stopped short of) or in a step it finished (FMI 3.0's
  terminateSimulation, flagged in ``time_events.terminated``); FMI 1.0
  has no such status (a Discard fails the run).
- ``c_getState(comp, byref(state))``, ``c_setState(comp, state)``,
  ``c_freeState``: the FMU state, where ``can_get_set_state``;
  ``save_state``/``restore_state`` keep one saved state per instance
  (``_state``), with whatever the face keeps beside the FMU's (FMI 3.0's
  announced next event, the Model Exchange wrapper's integrator).

Everything else is off the hot path: ``instantiate``, ``setup`` (start
time, tolerance, parameters, Initialization Mode entered), ``exit_init``,
``reset``, ``free``; ``set_values``/``get_values`` of every type;
``get_real`` and kin; ``terminated``, ``last_successful_time``.

Capabilities (attributes, read once at set-up):

- ``can_interpolate_inputs``: takes input polynomials;
  ``polynomial_inputs_refusal(fix)``: why the master must not give them
  at all (an FMI 3.0 FMU without intermediate update), else None;
- ``outputs_after_inputs``: outputs may be read after inputs are set with
  no step between (FMI 2.0 4.2.4 and FMI 3.0 Step Mode forbid it unless
  declared);
- ``can_get_set_state``; ``max_output_derivative_order``;
- ``has_event_mode``: the instance runs with FMI 3.0's Event Mode
  (its events are handled by the face, inside ``c_doStep``);
- ``time_events``: a ctypes struct shared with the compiled core that
  announces the FMU's next time event (``next_event_time``, s; a
  communication point lands on it) and its wish to end
  (``terminated``, ``end_time``), or None for a face that announces none;
- ``statistics()``: the face's own counts for the run's summary (the
  Model Exchange wrapper's integrator), or None.

Names in messages: the engine names a call by its contract name
(``named("doStep")``, ``named("setReal")``...); each face answers with
its own function's name (fmi2DoStep, fmi3DoStep, fmiDoStep, the Model
Exchange step). No face rewrites another's names.

How the compiled core calls it: ``core_calls(lib)`` gives the C
functions the core's port calls (``CORE_CALLS``, in that order, each with
the fmi2-shaped C signature above) and the pointer they take first: the
FMU's own symbols for an FMI 2.0 Co-Simulation FMU; the core's own adapter
(``cw1_*``, ``cw3_*``, ``cwme_*``) on the face's shared struct for the
others. The core never asks which it is.

Where the next features land
----------------------------

- FMI 3.0 clocks and Scheduled Execution: the clocks an FMU declares are
  a capability of the contract (next to ``has_event_mode``); a face that
  has them announces its clock ticks as it announces time events (a field
  of ``time_events``: the next tick, s, per clock) and takes
  "activate clock k at t" through a contract call that the FMI 3.0 face
  implements in Event Mode (``cs3.Instance3._handle_event`` is where the
  FMU's event iteration already runs). Other faces say they have no
  clocks; the master asks the capability, never the version.
- FMI 3.0 Event Mode driven by the master (events between FMUs): a
  contract call "enter event mode, update discrete states, back to step
  mode" beside ``c_doStep``, which the FMI 3.0 face implements with
  ``_handle_event`` and the others as "nothing to do".
- A multi-rate step: the master steps an instance by its own step size
  through the same ``c_doStep``; what differs per instance (its rate,
  whether it can take a step that does not end on the master's grid) is
  a capability here; the schedule itself belongs to the master.
"""

from __future__ import annotations

from ctypes import byref, c_char_p, c_double, c_int, c_uint, c_void_p
from pathlib import Path

from ..errors import ParametersRefused, SceneError, SimulationError, SimulationEnded, UsageError
from .calls import (DISCARD, FATAL, NO_MESSAGE, STATUS_NAMES, WARNING, crash_of, crashes, guard_library,
                    unattributed)
from .description import default_tolerance, default_tolerance_problem, outputs_after_inputs, read_fmu
from .variables import instance_variables

# The calls a compiled core's port makes, in the order core_calls gives them.
CORE_CALLS = ("doStep", "getReal", "setReal", "setInputDerivatives", "getOutputDerivatives", "getState",
              "setState")


class Instance:
    """An FMU instance as the master sees it: the contract (see the
    module's docstring) and the code the faces share."""

    # The face's own names of the contract's calls, in messages (named()).
    CALL_NAMES: dict[str, str] = {}
    # Instances freed in this process: a master looks for a freed instance
    # of its own before a run only when this changed (systems have thousands).
    frees = 0
    # Its binary under the core's crash handler (guard_library's address, or
    # None), and the crashes of that binary before this instance was made.
    _guarded: int | None = None
    _crashes_seen = 0
    # Capabilities a face sets when it has them.
    can_interpolate_inputs = False
    can_get_set_state = False
    max_output_derivative_order = 0
    has_event_mode = False
    time_events = None  # a face's shared struct: next_event_time, terminated, end_time
    arrays: dict[str, tuple[int, int]] = {}  # FMI 3.0 array variables: name -> (vr, values) (cs3.Instance3)
    elements: dict[str, list[str]] = {}  # FMI 3.0 array variables: name -> its element names, row-major
    # What messages call the FMU where its path is a copy (an SSP archive's
    # member, "x.ssp/resources/m.fmu"); None: its path.
    label: str | None = None
    instantiation_note: str | None = None  # what the face changed of its own setup (said once by the master)

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

    @property
    def shown(self) -> str:
        return self.label or str(self.path)

    def __reduce_ex__(self, protocol):
        raise UsageError(f"the FMU instance {self.name} cannot be pickled or copied: it is a loaded library "
                         "and its C state")

    def clock_table(self):
        """The FMU's clocks as this face serves them (fmi.clocks.ClockTable),
        or None: only FMI 3.0 Co-Simulation and Scheduled Execution have any."""
        return None

    def named(self, call: str) -> str:
        """This face's name of the contract's call `call` ("doStep",
        "getReal", "setReal", ...), for messages."""
        return self.CALL_NAMES.get(call, call)

    def _read_capabilities(self) -> None:
        """What the FMU's <CoSimulation> element declares (a Model Exchange wrapper says its own)."""
        cs = self.md.coSimulation
        self.max_output_derivative_order = int(cs.maxOutputDerivativeOrder or 0)
        self.can_interpolate_inputs = bool(cs.canInterpolateInputs)
        self.can_get_set_state = bool(cs.canGetAndSetFMUstate)

    def _outputs_after_inputs(self) -> bool:
        """Whether the master may read outputs after setting inputs with no
        step between (engine/wiring.py): FMI 2.0 (4.2.4) and FMI 3.0's Step
        Mode forbid it unless the description says so in clockwork's
        annotation (description.declares_outputs_after_inputs)."""
        return outputs_after_inputs(self.path)

    def _guard(self, dll, names: tuple[str, ...]) -> None:
        """Put this instance's binary under the crash handler (`names`: the
        functions that may name the library, the first it has)."""
        self._guarded = guard_library(dll, names, self.name)
        self._crashes_seen = crashes(self._guarded)  # an earlier instance's crash is not this one's

    # -- what a face provides -------------------------------------------------

    def instantiate(self) -> None:
        raise NotImplementedError

    def core_calls(self, lib) -> tuple[int, tuple[int, ...]]:
        """(the pointer the core passes first, the addresses of the C
        functions of CORE_CALLS in that order) for the compiled core `lib`."""
        raise NotImplementedError

    def _free_instance(self) -> None:
        raise NotImplementedError

    def polynomial_inputs_refusal(self, fix: str) -> str | None:
        """Why inputs given as polynomials (extrapolation, strong coupling)
        must not reach this instance, with `fix` (what the user can change)
        in it; None when they may (taken, or held by the coupling)."""
        return None

    def statistics(self) -> dict | None:
        """The face's own counts for the run's summary, or None."""
        return None

    def terminated(self) -> bool:
        """The FMU asked to end the simulation (asked after a discarded step)."""
        return False

    def last_successful_time(self) -> float | None:
        """Where the FMU stopped in a discarded step, s, or None."""
        return None

    def ended(self, t: float, h: float | None = None) -> SimulationEnded | None:
        """The end this instance's FMU asked for, or None: `h` given, in the
        step from t it discarded; else in a step it finished (t: the last
        communication point, s, where the results end)."""
        ev = self.time_events
        if ev is not None and ev.terminated:
            end = ev.end_time
            return SimulationEnded(f"{self.name} ended the simulation (terminateSimulation) at t = {end!r} s; "
                                   f"results until {t!r} s", time=t, instance=self.name, fmu_time=end)
        if h is not None and self.terminated():
            end = self.last_successful_time()
            end = t if end is None else end
            return SimulationEnded(f"{self.name} ended the simulation at t = {end!r} s, in the step from "
                                   f"t = {t!r} s; results until {t!r} s", time=t, instance=self.name,
                                   fmu_time=end)
        return None

    # -- lifecycle --------------------------------------------------------------

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

    def setup(self, start: float, parameters: dict[str, object], tolerance: float | None = None) -> None:
        """The experiment's start and relative tolerance (when one is given:
        the scene's, else the FMU's DefaultExperiment's), parameters,
        Initialization Mode entered."""
        if tolerance is None:
            tolerance = self.default_tolerance
            problem = default_tolerance_problem(self.md)
            if problem:  # the scene layer refuses it first
                raise SceneError(f"{self.shown}: modelDescription.xml: DefaultExperiment tolerance = {tolerance:g}: "
                                 f"{problem}; or give master.tolerance")
        defined = tolerance is not None
        self.check(self.c_setup(self.component, int(defined), float(tolerance) if defined else 0.0, start, 0, 0.0),
                   self.named("setup"))
        self.set_values(parameters, "setting parameters", ParametersRefused)
        self.check(self.c_enterInit(self.component), self.named("enterInit"))

    def exit_init(self) -> None:
        self.check(self.c_exitInit(self.component), self.named("exitInit"), error=ParametersRefused)

    def reset(self) -> None:
        """Back to the state right after instantiation."""
        self.check(self.c_reset(self.component), self.named("reset"))
        del self.messages[:]  # an error after the reset must not quote one from before

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

    def check(self, status: int, what: str, time: float | None = None,
              error: type[SimulationError] = SimulationError) -> None:
        if status > WARNING:
            raise self.fail(what, status, time, error)

    # -- values of every type (not on the hot path) -----------------------

    def set_values(self, values: dict[str, object], what: str | None = None,
                   error: type[SimulationError] = SimulationError) -> None:
        """Set variables of any type, each through the call of its type."""
        what = what or self.CALL_NAMES["setValues"]
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

    def get_real(self, names: list[str]) -> list[float]:
        vrs = (c_uint * len(names))(*[self.variables[n].vr for n in names])
        out = (c_double * len(names))()
        self.check(self.c_getReal(self.component, vrs, len(names), out), self.named("getReal"))
        return list(out)

    def get_integer(self, names: list[str]) -> list[int]:
        vrs = (c_uint * len(names))(*[self.variables[n].vr for n in names])
        out = (c_int * len(names))()
        self.check(self.c_getInteger(self.component, vrs, len(names), out), self.named("getInteger"))
        return list(out)

    def get_string(self, names: list[str]) -> list[str]:
        vrs = (c_uint * len(names))(*[self.variables[n].vr for n in names])
        out = (c_char_p * len(names))()
        self.check(self.c_getString(self.component, vrs, len(names), out), self.named("getString"))
        return [(x or b"").decode("utf-8", "replace") for x in out]

    def get_boolean(self, names: list[str]) -> list[bool]:
        vrs = (c_uint * len(names))(*[self.variables[n].vr for n in names])
        out = (c_int * len(names))()
        self.check(self.c_getBoolean(self.component, vrs, len(names), out), self.named("getBoolean"))
        return [bool(x) for x in out]

    def get_values(self, names: list[str]) -> list:
        """Values of any type, each through the get of its type
        (Enumeration as Integer); not on the hot path."""
        getters = {"Real": self.get_real, "Integer": self.get_integer, "Enumeration": self.get_integer,
                   "Boolean": self.get_boolean, "String": self.get_string}
        return [getters[self.variables[n].type]([n])[0] for n in names]

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
        # The name by subscript, not named(): a checkpoint saves at every event.
        self.check(self.c_getState(self.component, byref(self._state)), self.CALL_NAMES["getState"], t)

    def restore_state(self, t: float | None = None) -> None:
        self.check(self.c_setState(self.component, self._state), self.CALL_NAMES["setState"], t)
