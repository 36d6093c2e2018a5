"""A Model Exchange FMU as an instance that steps like a Co-Simulation one.

``MEInstance`` implements the instance contract (``fmi/contract.py``:
``c_doStep``, ``c_setReal``, ``c_setInputDerivatives``,
``c_getOutputDerivatives``, ``c_getState``...), so that the stepping loop,
the coupling, the event location and the checkpoints serve it unchanged,
mixed with Co-Simulation FMUs. It composes two parts: the FMU's Model
Exchange face (``fmi/me1.py`` for FMI 1.0, ``fmi/me2.py`` for FMI 2.0,
``fmi/me3.py`` for FMI 3.0:
the FMU's functions, which know nothing of integration; the factory,
``instances.make_instance``, picks it) and the integration (``me_step.py``:
the algorithm, its events, and the integrators ``rk.py`` and
``cvode.py``). Towards the master it behaves as a Co-Simulation FMU with
these capabilities would:

- it takes input derivatives (``canInterpolateInputs``) and sets the
  inputs' polynomials wherever it evaluates the FMU between communication
  points;
- it offers output derivatives of outputs that are states (the first from
  the derivatives, the second where a state's derivative is itself a
  state), for the master's coupling and event location;
- its FMU state is the FMU's fmi2GetFMUstate (where the FMU declares
  canGetAndSetFMUstate) plus the wrapper's own (time, states, step size,
  next event time, indicators, input polynomials, solver), so rollback,
  replay and shooting work;
- an FMU that ends the simulation (terminateSimulation) makes a step
  return Discard and ``terminated`` true (``last_successful_time``: where
  it stopped), the contract's "the FMU asks to end";
- values other than continuous inputs (parameters, discrete inputs) set
  during the run go through event mode, as Model Exchange requires.

The wrapper's state lives in a ctypes struct (``_ME``) shared with the
compiled core's twin (src_c/master/cw_me.c, the ``cwme_*`` functions):
the core steps the same instance with the same bits.

An FMU that declares both interfaces runs as Co-Simulation unless asked
for Model Exchange (``instances.make_instance(..., interface="model-exchange")``,
the scene's ``interface = "model-exchange"``); one that declares only
Model Exchange always runs so.
"""

from __future__ import annotations

import ctypes
import math
from ctypes import Structure, c_char, c_double, c_int, c_longlong, c_size_t, c_void_p
from dataclasses import dataclass

from ..errors import SceneError, SimulationError
from . import cvode, rk
from .events import input_polynomial
from ..fmi.calls import ERROR, OK, WARNING
from ..fmi.clocks import clock_table as read_clock_table
from ..fmi.contract import CORE_CALLS, Instance
from ..fmi.description import fmi1_details
from .me_step import (AUTO, FMU_CALLS, CONTINUOUS, CVODE, DEFAULT_RTOL, EVENT, FAIL_CVODE, FAIL_LOCATE, FAIL_RK,
                      FAIL_SETTLE, FAIL_TIME, FAIL_TIME_EVENTS, INITIALIZATION, INSTANTIATED, MAX_CVODE_STEPS,
                      MAX_EVENT_ITERATIONS, MAX_RK_STATES, MAX_TRIALS, METHOD_NAMES, RK_FAILURES, SOLVERS, STATS,
                      ModelExchangeSteps)

INTERFACES = ("co-simulation", "model-exchange")


@dataclass(frozen=True)
class MEOptions:
    """How a Model Exchange FMU is integrated: master.me_solver and the
    master's event time tolerance (s). The relative tolerance comes with
    fmi2SetupExperiment (master.tolerance, else the DefaultExperiment's)."""

    solver: str = "auto"
    event_time_tolerance: float = 1e-10


class _ME(Structure):
    """The wrapper's state, shared with cw_me.c's cw_me (same layout)."""

    _fields_ = [(n, c_void_p) for n in (
        "instance", "setTime", "setStates", "getDerivatives", "getIndicators", "getStates", "getNominals",
        "completedStep", "enterEventMode", "update", "enterContinuousMode", "getReal", "setReal",
        "getState", "setState", "calls", "sundials", "rk",
        "x", "xbuf", "xw", "xd", "dx", "nominal", "atolv", "z_prev", "z", "z_end", "z_lo", "z0",
        "in_vr", "u0", "d1", "d2", "tref", "in_val", "state_vr", "der_state", "saved",
        "cv_mem", "cv_ctx", "cv_y", "cv_abstol", "cv_dky", "cv_A", "cv_LS")] + [
        (n, c_double) for n in (
            "time", "next_event_time", "end_time", "rtol", "event_time_tolerance", "h_next", "err_t",
            "saved_time", "saved_next_event_time", "saved_end_time", "saved_h_next")] + [
        (n, c_longlong) for n in STATS] + [
        (n, c_int) for n in (
            "n", "nz", "n_in", "solver", "method", "stiff_count", "nonstiff_count", "terminated",
            "mode", "poly", "inputs_dirty", "restart", "cv_owner", "failed_call", "failed_status",
            "failed_detail", "needs_completed", "saved_method", "saved_stiff_count", "saved_nonstiff_count",
            "saved_terminated", "saved_poly", "saved_mode", "pad4_")]


class MEInstance(Instance):
    """A Model Exchange FMU behind the instance contract: its Model
    Exchange face `face` (me1.ModelExchange1, me2.ModelExchange2,
    me3.ModelExchange3) and the integration `steps` (ModelExchangeSteps,
    with rk and cvode), which it holds, binds to the face's calls and
    delegates the step to."""

    joins_me_group = True

    def clock_table(self):
        """Clocks are served in Co-Simulation and Scheduled Execution only."""
        if read_clock_table(self.md):
            raise SceneError(f"{self.name} ({self.path.name}): its clocks are served in Co-Simulation and "
                             "Scheduled Execution only, not through Model Exchange (interface = "
                             "'co-simulation')")
        return None

    def __init__(self, name, path, model_description, face, options: MEOptions | None = None):
        super().__init__(name, path, model_description)
        md = self.md
        self.face = face
        self.CALL_NAMES = face.CALL_NAMES  # named(): the wrapper's calls, in its face's words
        self.options = options or MEOptions()
        if self.options.solver not in SOLVERS:
            raise SceneError(f"master.me_solver = {self.options.solver!r}: expected one of "
                             f"{', '.join(map(repr, SOLVERS))}")
        me_md = md.modelExchange
        self.can_get_set_state = bool(me_md.canGetAndSetFMUstate)
        needs_completed = bool(me_md.needsCompletedIntegratorStep)
        states = [d.variable.derivative for d in md.derivatives]
        n = len(states)
        nz = int(md.numberOfEventIndicators or 0)
        # Inputs that may change in continuous-time mode (the others are set in event mode).
        inputs = [v for v in md.modelVariables
                  if v.causality == "input" and v.type == "Real" and v.variability == "continuous"]
        n_in = len(inputs)
        self.continuous_inputs = {}  # value reference -> position (the first of aliases, as cw_me.c finds it)
        for k, v in enumerate(inputs):
            self.continuous_inputs.setdefault(v.valueReference, k)
        state_vr = [v.valueReference for v in states]
        der_vr = [d.variable.valueReference for d in md.derivatives]
        der_state = [state_vr.index(v) if v in state_vr else -1 for v in der_vr]
        # Output derivatives: of outputs that are states (an output shares the state's value reference).
        orders = [2 if der_state[state_vr.index(v.valueReference)] >= 0 else 1
                  for v in md.modelVariables if v.causality == "output" and v.valueReference in state_vr]
        self.max_output_derivative_order = max(orders, default=0)
        self.can_interpolate_inputs = n_in > 0
        self.event_indicators = []  # the FMU's own indicators are located inside the wrapper
        self.state_names = [v.name for v in states]

        me = self.me = _ME(n=n, nz=nz, n_in=n_in,
                           solver=SOLVERS[self.options.solver],
                           event_time_tolerance=float(self.options.event_time_tolerance),
                           needs_completed=int(needs_completed))
        steps = self.steps = ModelExchangeSteps(me, [v.valueReference for v in inputs], state_vr, der_state,
                                                needs_completed)
        for k, v in enumerate(inputs):
            steps.u0[k] = float(v.start) if v.start not in (None, "") else 0.0
        self._core = None  # the compiled core's cw_rk workspace, once the core steps this instance
        self._reset_wrapper()

    def _read_capabilities(self) -> None:
        """Model Exchange has no Co-Simulation capabilities: set in __init__."""

    def _outputs_after_inputs(self) -> bool:
        """The wrapper's outputs follow its inputs (Model Exchange computes them on the get)."""
        return True

    # -- loading -------------------------------------------------------------

    def instantiate(self) -> None:
        """The face loads and instantiates the FMU; the wrapper binds its calls."""
        self._slave = self.face.instantiate(self)
        self.component = self._slave.component
        self._bind(self._slave.dll)

    def _bind(self, dll) -> None:
        """The face's functions, bound once here: the algorithm's calls, the
        struct's addresses, and the contract's calls the wrapper serves."""
        face = self.face
        face.bind(dll, self.component, self)
        self._fmu_calls(face)
        self.c_getInteger, self.c_setInteger = face.get_integer, face.set_integer
        self.c_getBoolean, self.c_setBoolean = face.get_boolean, face.set_boolean
        self.c_getString, self.c_setString = face.get_string, face.set_string
        self.c_freeState = face.free_state
        fmu_reset = face.reset
        self.c_reset = lambda c: self._reset_call(fmu_reset)
        self.c_terminate = face.terminate
        setup, enter_init, exit_init = face.setup, face.enter_init, face.exit_init

        def c_setup(c, tol_defined, tol, start, stop_defined, stop):
            self._setup_wrapper(tol_defined, tol, start)
            return setup(c, tol_defined, tol, start, stop_defined, stop)

        self.c_setup = c_setup
        self.c_enterInit = lambda c: self._enter_init(enter_init(c))
        self.c_exitInit = lambda c: self._exit_init(exit_init(c))
        self.steps.update, self.steps.completed_step = face.update, face.completed_step
        values = face.values  # FMI 3.0: every type through its own fmi3Get*/fmi3Set*
        self._set_values_now = super().set_values if values is None else values.set_values
        if values is not None:  # an instance attribute: no Python call of its own
            self.get_values = values.get_values

    def _fmu_calls(self, face) -> None:
        """Bind the FMU functions the algorithm calls, and hand their addresses to the struct."""
        comp = self.component
        me = self.me
        me.instance = comp
        f = face.functions
        for name, fn_ in f.items():
            setattr(me, name, ctypes.cast(fn_, c_void_p).value)
        self.steps.set_time = lambda t: f["setTime"](comp, t)
        self.steps.set_states = lambda x, n: f["setStates"](comp, x, n)
        self.steps.get_derivatives = lambda dx, n: f["getDerivatives"](comp, dx, n)
        self.steps.get_indicators = lambda z, n: f["getIndicators"](comp, z, n)
        self.steps.get_states = lambda x, n: f["getStates"](comp, x, n)
        self.steps.get_nominals = lambda x, n: f["getNominals"](comp, x, n)
        self.steps.enter_event = lambda: f["enterEventMode"](comp)
        self.steps.enter_continuous = lambda: f["enterContinuousMode"](comp)
        self.steps.set_inputs = face.set_inputs
        self._fmu_set_real = face.set_real
        self._fmu_get_state, self._fmu_set_state = f["getState"], f["setState"]
        self.c_getReal = face.get_real
        self.c_setReal = self._set_real
        self.c_setInputDerivatives = self._set_input_derivatives
        self.c_getOutputDerivatives = self._output_derivatives
        self.c_getState = self._get_state
        self.c_setState = self._set_state
        self.c_doStep = self.steps.do_step

    # -- the wrapper's own state ------------------------------------------------

    def _reset_wrapper(self) -> None:
        me = self.me
        me.time = me.err_t = 0.0
        me.next_event_time = math.inf
        me.end_time = math.nan
        me.rtol = DEFAULT_RTOL
        me.h_next = 0.0
        me.mode = INSTANTIATED
        me.terminated = me.poly = me.inputs_dirty = me.failed_call = me.failed_status = me.failed_detail = 0
        me.stiff_count = me.nonstiff_count = 0
        me.restart = 1
        for name in STATS:
            setattr(me, name, 0)
        for k in range(me.n_in):
            self.steps.d1[k] = self.steps.d2[k] = self.steps.tref[k] = 0.0

    def _setup_wrapper(self, tol_defined, tol, start) -> None:
        me = self.me
        me.rtol = float(tol) if tol_defined else DEFAULT_RTOL
        me.time = start
        me.method = self._choose_method()
        for k in range(me.n_in):
            self.steps.tref[k] = start

    def _enter_init(self, status: int) -> int:
        if status <= WARNING:
            self.me.mode = INITIALIZATION
        return status

    def _exit_init(self, status: int) -> int:
        """After fmi2ExitInitializationMode (event mode): settle, then
        continuous-time mode with the states, nominals and indicators; the solver chosen."""
        me = self.me
        if status > WARNING:
            return status
        me.mode = EVENT
        st = self.steps.settle(None)
        if st > WARNING:
            return st
        if me.n and not me.terminated:
            if self.steps.check(self.steps.get_states(self.steps.x, me.n), 9):
                return ERROR
            if self.steps.read_nominals() > WARNING:
                return ERROR
        return OK

    def _choose_method(self) -> int:
        me = self.me
        solver = me.solver
        if solver == CVODE or (solver == AUTO and me.n > MAX_RK_STATES):
            problem = cvode.problem()
            if problem is not None:
                raise SceneError(f"{self.name} ({self.path.name}): {problem}")
            return CVODE
        if me.n > MAX_RK_STATES:
            raise SceneError(f"master.me_solver = {self.options.solver!r}: {self.name} ({self.path.name}) has "
                             f"{me.n} continuous states, the Runge-Kutta pairs take at most {MAX_RK_STATES}; "
                             f"use 'cvode' or 'auto'")
        return rk.choose(0 if solver == AUTO else solver, me.rtol)

    # -- the master's calls --------------------------------------------------------

    def _set_real(self, comp, vr, n, values) -> int:
        """fmi2SetReal: continuous inputs directly, their polynomials held
        from the wrapper's time; anything else in event mode."""
        me = self.me
        index = self.continuous_inputs
        ks = [index.get(vr[j], -1) for j in range(n)]
        if me.mode == CONTINUOUS and min(ks, default=0) < 0:
            st = self._set_in_event_mode(lambda: self._fmu_set_real(self.component, vr, n, values))
        else:
            st = self._fmu_set_real(self.component, vr, n, values)
        if st > WARNING or not me.n_in:
            return st
        for j, k in enumerate(ks):
            if k < 0:
                continue
            dt = me.time - self.steps.tref[k]
            now = input_polynomial(self.steps.u0[k], self.steps.d1[k], self.steps.d2[k], dt)
            if values[j] != now or self.steps.d1[k] != 0.0 or self.steps.d2[k] != 0.0:
                me.inputs_dirty = me.restart = 1
            self.steps.u0[k] = values[j]
            self.steps.d1[k] = self.steps.d2[k] = 0.0
            self.steps.tref[k] = me.time
        self._recheck_poly()
        return st

    def _recheck_poly(self) -> None:
        me = self.me
        me.poly = int(any(self.steps.d1[k] != 0.0 or self.steps.d2[k] != 0.0 for k in range(me.n_in)))

    def _set_input_derivatives(self, comp, vr, n, order, values) -> int:
        """fmi2SetRealInputDerivatives on continuous inputs (order 1 or 2),
        re-based at the wrapper's time as the FMI 2.0 runtime does."""
        me = self.me
        index = self.continuous_inputs
        for j in range(n):
            if index.get(vr[j], -1) < 0 or order[j] not in (1, 2) or not math.isfinite(values[j]):
                return ERROR
        for j in range(n):
            k = index[vr[j]]
            if self.steps.tref[k] != me.time:
                dt = me.time - self.steps.tref[k]
                self.steps.u0[k] = input_polynomial(self.steps.u0[k], self.steps.d1[k], self.steps.d2[k], dt)
                self.steps.d1[k] = self.steps.d2[k] = 0.0
                self.steps.tref[k] = me.time
            if order[j] == 1:
                if self.steps.d1[k] != values[j]:
                    me.restart = 1
                self.steps.d1[k] = values[j]
            else:
                if self.steps.d2[k] != values[j]:
                    me.restart = 1
                self.steps.d2[k] = values[j]
        self._recheck_poly()
        return OK

    def _output_derivatives(self, comp, vr, n, order, out) -> int:
        """Derivatives of outputs that are states: the first from the
        derivatives at the current point, the second where the state's
        derivative is a state too; Error for any other."""
        me = self.me
        if me.mode != CONTINUOUS or not me.n:
            return ERROR
        state_vr = self.steps.state_vr[:me.n]
        picks = []
        for j in range(n):
            if vr[j] not in state_vr or order[j] not in (1, 2):
                return ERROR
            i = state_vr.index(vr[j])
            if order[j] == 2:
                i = self.steps.der_state[i]
                if i < 0:
                    return ERROR
            picks.append(i)
        st = self.steps.get_derivatives(self.steps.dx, me.n)
        me.rhs += 1
        if st > WARNING:
            return st
        for j, i in enumerate(picks):
            out[j] = self.steps.dx[i]
        return OK

    def _set_in_event_mode(self, setter) -> int:
        """A value that Model Exchange takes in event mode only: enter it, set, settle."""
        if self.steps.check(self.steps.enter_event(), 6):
            return ERROR
        self.me.mode = EVENT
        st = setter()
        if st > WARNING:
            return st
        return max(st, self.steps.settle("input_events"))

    def set_values(self, values: dict[str, object], what: str | None = None,
                   error: type[SimulationError] = SimulationError) -> None:
        """Values of any type; in continuous-time mode all but continuous
        inputs go in together in one pass through event mode."""
        what = what or self.CALL_NAMES["setValues"]
        me = self.me
        if me.mode != CONTINUOUS or all(self.variables[n].vr in self.continuous_inputs for n in values):
            self._set_values_now(values, what, error)
            return
        self.check(self.steps.enter_event(), self.face.NAMES[FMU_CALLS[6]], me.time)
        me.mode = EVENT
        try:
            self._set_values_now(values, what, error)
        finally:
            st = self.steps.settle("input_events")
        self.check(st, what, me.time, error)

    def _get_state(self, comp, state) -> int:
        """fmi2GetFMUstate, and the wrapper's own state beside it."""
        st = self._fmu_get_state(self.component, state)
        if st > WARNING:
            return st
        me = self.me
        saved = self.steps.saved
        n, nz, n_in = me.n, me.nz, me.n_in
        saved[0:n] = self.steps.x[:n]
        saved[n:n + nz] = self.steps.z_prev[:nz]
        for k in range(n_in):
            base = n + nz + 4 * k
            saved[base:base + 4] = [self.steps.u0[k], self.steps.d1[k], self.steps.d2[k], self.steps.tref[k]]
        me.saved_time, me.saved_next_event_time, me.saved_end_time, me.saved_h_next = (
            me.time, me.next_event_time, me.end_time, me.h_next)
        me.saved_method, me.saved_stiff_count, me.saved_nonstiff_count = me.method, me.stiff_count, me.nonstiff_count
        me.saved_terminated, me.saved_poly, me.saved_mode = me.terminated, me.poly, me.mode
        return st

    def _set_state(self, comp, state) -> int:
        st = self._fmu_set_state(self.component, state)
        if st > WARNING:
            return st
        me = self.me
        saved = self.steps.saved
        n, nz, n_in = me.n, me.nz, me.n_in
        if n:
            self.steps.x[:n] = saved[0:n]
        if nz:
            self.steps.z_prev[:nz] = saved[n:n + nz]
        for k in range(n_in):
            base = n + nz + 4 * k
            self.steps.u0[k], self.steps.d1[k], self.steps.d2[k], self.steps.tref[k] = saved[base:base + 4]
        me.time, me.next_event_time, me.end_time, me.h_next = (
            me.saved_time, me.saved_next_event_time, me.saved_end_time, me.saved_h_next)
        me.method, me.stiff_count, me.nonstiff_count = me.saved_method, me.saved_stiff_count, me.saved_nonstiff_count
        me.terminated, me.poly, me.mode = me.saved_terminated, me.saved_poly, me.saved_mode
        me.restart = 1
        me.inputs_dirty = 0
        return st

    def _reset_call(self, fmu_reset) -> int:
        st = fmu_reset(self.component)
        if st <= WARNING:
            self._reset_wrapper()
        return st

    def core_state(self, lib) -> int:
        """The address of the shared struct, made ready for the compiled
        core's wrapper (its Runge-Kutta workspace, CVode's functions)."""
        if self._core is None:
            lib.cwme_sizeof_rk.restype = c_size_t
            lib.cwme_prepare.argtypes = [c_void_p]
            lib.cwme_prepare.restype = None
            if lib.cwme_max_states() != MAX_RK_STATES:
                raise SimulationError(f"the compiled core's Runge-Kutta pairs take {lib.cwme_max_states()} states, "
                                      f"the Python engine's {MAX_RK_STATES}: rebuild it with tools/setup.sh")
            self._core = (c_char * lib.cwme_sizeof_rk())()
            self.me.rk = ctypes.addressof(self._core)
            # how the core calls this FMU's version-shaped functions: the table its face names
            self.me.calls = ctypes.addressof(c_char.in_dll(lib, self.face.CORE_CALLS_TABLE))
            sun = cvode.sundials()
            if sun is not None:
                self.me.sundials = ctypes.addressof(sun.table)
            lib.cwme_prepare(ctypes.addressof(self.me))
        return ctypes.addressof(self.me)

    # -- what the master asks -------------------------------------------------------

    def core_calls(self, lib) -> tuple[int, tuple[int, ...]]:
        """The core's Model Exchange wrapper (cwme_*, cw_me.c) on this instance's shared ``_ME``."""
        return self.core_state(lib), tuple(ctypes.cast(getattr(lib, "cwme_" + name), c_void_p).value
                                           for name in CORE_CALLS)

    def terminated(self) -> bool:
        return bool(self.me.terminated)

    def last_successful_time(self) -> float | None:
        t = self.me.end_time
        return None if math.isnan(t) else t

    def statistics(self) -> dict:
        """The integration's counts and settings for the summary."""
        me = self.me
        solver = METHOD_NAMES.get(me.method, "none") if me.n else "none (no continuous states)"
        out = {"interface": "model-exchange", "solver": solver,
               "requested_solver": self.options.solver, "tolerance": me.rtol,
               "continuous_states": me.n, "event_indicators": me.nz}
        out.update({name: int(getattr(me, name)) for name in STATS})
        return out

    def fail(self, what, status, time=None, error=None):
        """The failure, naming what failed inside the wrapper where something did."""
        me = self.me
        code, me.failed_call = me.failed_call, 0
        if code:
            name = self.named("doStep")
            step = what.replace(name + "(", name + " (")
            if code in FMU_CALLS:
                what = f"{self.face.NAMES[FMU_CALLS[code]]} at t = {me.err_t!r} s, in {step}"
            else:
                self.messages.append((ERROR, self._failure_text(code)))
                what = f"{step} at t = {me.err_t!r} s"
        return super().fail(what, status, time, error or SimulationError)

    def _failure_text(self, code: int) -> str:
        me = self.me
        method = METHOD_NAMES.get(me.method, "?")
        if code == FAIL_RK:
            return f"{method} at rtol {me.rtol:g}: {RK_FAILURES.get(me.failed_detail, 'failed')}"
        if code == FAIL_CVODE:
            detail = (f"flag {me.failed_detail}" if me.failed_detail
                      else f"more than {MAX_CVODE_STEPS} steps in one communication step")
            return f"CVode at rtol {me.rtol:g} failed ({detail})"
        if code == FAIL_SETTLE:
            return f"the discrete states did not settle in {MAX_EVENT_ITERATIONS} event iterations"
        if code == FAIL_TIME:
            return (f"asked to step from a time that is not the FMU's (t = {me.time!r} s) "
                    f"or outside continuous-time mode")
        if code == FAIL_LOCATE:
            return f"the state event could not be located in {MAX_TRIALS} trials"
        if code == FAIL_TIME_EVENTS:
            return f"more than {MAX_EVENT_ITERATIONS} time events at one time (nextEventTime does not advance)"
        return f"failure {code}"

    # -- lifecycle ----------------------------------------------------------------

    def _free_instance(self) -> None:
        if self.me.cv_mem or self.me.cv_ctx:
            cvode.free(self.me)
        self.face.free(self._slave, self.component)


def interface_of(md, requested: str | None) -> str:
    """The interface a component runs through: `requested` ("co-simulation"
    or "model-exchange") where the FMU has it, else Co-Simulation where it
    has it, else Model Exchange. SceneError for an interface the FMU lacks."""
    has = {"co-simulation": md.coSimulation is not None, "model-exchange": md.modelExchange is not None}
    if requested:
        if requested not in has:
            raise SceneError(f"interface = {requested!r}: expected one of {', '.join(map(repr, INTERFACES))}")
        if not has[requested]:
            other = "no <CoSimulation> element" if requested == "co-simulation" else "no <ModelExchange> element"
            shown = {"co-simulation": "Co-Simulation", "model-exchange": "Model Exchange"}[requested]
            raise SceneError(f"{md.modelName} has no {shown} interface ({other})")
        return requested
    return "co-simulation" if has["co-simulation"] else "model-exchange"


def model_exchange_problem(md) -> str | None:
    """Why the Model Exchange wrapper cannot run this FMU, or None: FMI 3.0
    array variables (the Co-Simulation adapter serves them, the wrapper's
    states and inputs are scalars); FMI 1.0 negated aliases (the
    Co-Simulation face renumbers them, the wrapper does not)."""
    negated = sorted(fmi1_details(md).negated)
    if negated:
        return (f"Model Exchange with FMI 1.0 negatedAlias variables is not supported ({', '.join(negated[:8])}"
                f"{', ...' if len(negated) > 8 else ''})")
    arrays = [v.name for v in md.modelVariables if getattr(v, "shape", None)]
    if arrays:
        return (f"Model Exchange with FMI 3.0 array variables is not supported ({', '.join(arrays[:8])}"
                f"{', ...' if len(arrays) > 8 else ''}); run it through its Co-Simulation interface if it has one")
    return None
