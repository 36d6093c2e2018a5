"""The step of a Model Exchange FMU: its integrator and its events.

A Model Exchange FMU computes derivatives; the importer integrates. The
wrapper (``model_exchange.py``) makes it an instance that steps like a
Co-Simulation one: ``do_step(t, h)`` integrates the continuous states from
t to t + h and handles every event on the way:

- the integrator: one of the project's embedded Runge-Kutta pairs with
  dense output (``rk.py``, the twin of cw_rk.c: Dormand-Prince 5(4) or
  8(5,3)), or CVode's BDF for stiff models (``cvode.py``); "auto" starts
  with the pair the tolerance asks for and switches to CVode for good when
  Hairer's stiffness test fires on STIFF_STEPS accepted steps;
- state events: after each accepted step the event indicators are read;
  where one changed sign the crossing is located on the integrator's dense
  output (Illinois brackets, ``events.Illinois``) to the master's
  event_time_tolerance, and the step ends just past it;
- time events at the FMU's nextEventTime (the integration stops exactly
  there), step events from fmi2CompletedIntegratorStep's enterEventMode,
  and a crossing caused by inputs that jumped at the communication point;
- each event: event mode, fmi2NewDiscreteStates (fmi3UpdateDiscreteStates)
  until the discrete states settle, new states and nominals where the FMU
  changed them, continuous-time mode, the integrator restarted;
- terminateSimulation ends the run cleanly: a step the FMU ended short is
  refused with Discard and ``terminated``, as an FMI 2.0 Co-Simulation FMU
  does (the master turns that into errors.SimulationEnded);
- inputs between communication points are the polynomials the master
  hands over with fmi2SetRealInputDerivatives (u0 + d1 dt + d2 dt^2 / 2),
  set at every time the FMU is evaluated.

Everything the wrapper keeps from one call to the next is in its ctypes
struct (``model_exchange._ME``), shared with the compiled core's twin in
src_c/master/cw_me.c, which runs the same algorithm expression for
expression: either engine can take the next step.
"""

from __future__ import annotations

import math
from ctypes import addressof, c_double, c_int, c_uint

from . import cvode, rk as rkmod
from .events import Illinois, crossed, earliest, input_polynomial
from ..fmi.calls import DISCARD, ERROR, OK, WARNING

# Solvers (MEOptions.solver, the struct's `solver`) and the method in use (`method`).
AUTO, DP54, DOP853, CVODE = 0, 1, 2, 3
SOLVERS = {"auto": AUTO, "dp54": DP54, "dop853": DOP853, "cvode": CVODE}
METHOD_NAMES = {DP54: "DP5(4)", DOP853: "DOP853", CVODE: "CVode BDF"}
DEFAULT_RTOL = 1e-6  # without master.tolerance and a DefaultExperiment tolerance
MAX_RK_STATES = 256  # CW_RK_MAXN of the compiled core: more states take CVode
STIFF_LIMIT = {DP54: 3.25, DOP853: 6.1}  # h |lambda| at the edge of each pair's stability region
STIFF_STEPS = 15  # accepted steps over the edge that make a model stiff (Hairer's DOPRI5, DOP853)
NONSTIFF_RESET = 6  # steps inside it that clear the count
MAX_EVENT_ITERATIONS = 1000  # event-mode updates per event, and events at one time
MAX_CVODE_STEPS = 1000000  # per step of the master, as cw_rk's bound
MAX_TRIALS = 200  # event location
SAFEGUARD_TRIALS = 4  # trials that must halve the bracket, else a bisection

# Modes of the FMU (the struct's `mode`).
INSTANTIATED, INITIALIZATION, CONTINUOUS, EVENT = 0, 1, 2, 3
# How an integration ended.
REACHED, STATE, STEP, TERMINATE, STIFF, FAILED = range(6)
# What failed (the struct's failed_call): an FMU function of the face (its
# name: the face's NAMES, me2.py and me3.py) or the wrapper.
FMU_CALLS = {1: "setTime", 2: "setStates", 3: "getDerivatives", 4: "getIndicators", 5: "completedStep",
             6: "enterEventMode", 7: "update", 8: "enterContinuousMode", 9: "getStates", 10: "getNominals",
             11: "setReal"}
FAIL_SETTLE, FAIL_TIME, FAIL_RK, FAIL_CVODE, FAIL_LOCATE, FAIL_TIME_EVENTS = 20, 21, 22, 23, 24, 25
RK_FAILURES = {rkmod.STEP_TOO_SMALL: "the step size fell below the resolution of time",
               rkmod.TOO_MANY_STEPS: f"more than {rkmod.MAX_STEPS} steps in one communication step",
               rkmod.NONFINITE: "the derivatives are not finite"}
STATS = ("steps", "rejected", "rhs", "state_events", "time_events", "step_events", "input_events",
         "event_iterations", "switches")


# The arrays of the struct `me` that the algorithm allocates and both engines share.
SHARED_ARRAYS = ("x", "xbuf", "xw", "xd", "dx", "nominal", "atolv", "z_prev", "z", "z_end", "z_lo", "z0",
                 "in_vr", "u0", "d1", "d2", "tref", "in_val", "state_vr", "der_state", "saved")


class ModelExchangeSteps:
    """The wrapper's algorithm, a part that ``model_exchange.MEInstance``
    (and ``me_group.MEGroup``) holds and delegates to: the integration's
    state (the struct `me`, model_exchange._ME, with its arrays ``x``,
    ``atolv``, ``z_prev``...; the integrators) and the FMU calls it makes
    (``set_time`` ... ``update``), which its holder binds once: a face's
    functions, or a group's over its members.

    `in_vr`: the continuous inputs' value references; `state_vr`: the
    states'; `der_state`: for each state's derivative, the state it is
    (its position) or -1."""

    def __init__(self, me, in_vr, state_vr, der_state, needs_completed: bool):
        self.me = me
        n, nz, n_in = me.n, me.nz, me.n_in

        def doubles(k):
            return (c_double * max(1, k))()

        self.x, self.xbuf, self.xw, self.xd, self.dx, self.nominal, self.atolv = (doubles(n) for _ in range(7))
        self.z_prev, self.z, self.z_end, self.z_lo, self.z0 = (doubles(nz) for _ in range(5))
        self.in_vr = (c_uint * max(1, n_in))(*in_vr)
        self.u0, self.d1, self.d2, self.tref, self.in_val = (doubles(n_in) for _ in range(5))
        self.state_vr = (c_uint * max(1, n))(*state_vr)
        self.der_state = (c_int * max(1, n))(*der_state)
        self.saved = doubles(n + nz + 4 * n_in)
        for field in SHARED_ARRAYS:  # the compiled core's wrapper (cw_me.c) works on these very arrays
            setattr(me, field, addressof(getattr(self, field)))
        self.needs_completed = needs_completed
        self.rk = rkmod.RungeKutta(n, DEFAULT_RTOL, 0.0)
        self.cv = None  # cvode.CVodeRun, at the first CVode step

    # -- failures ------------------------------------------------------------

    def _failed(self, call: int, status: int) -> int:
        """Note what failed (for ``fail``); returns the status to hand on."""
        me = self.me
        if not me.failed_call:
            me.failed_call, me.failed_status, me.err_t = call, status, me.time
        return status

    def check(self, status: int, call: int) -> bool:
        """True when the call failed (status above Warning), noted."""
        if status > WARNING:
            self._failed(call, status)
            return True
        return False

    # -- the FMU at a point ------------------------------------------------

    def _set_point(self, t: float, x) -> int:
        """Time t, the inputs' polynomials at t and the states x into the FMU."""
        me = self.me
        if self.check(self.set_time(t), 1):
            return ERROR
        if me.poly:
            vals = self.in_val
            for k in range(me.n_in):
                dt = t - self.tref[k]
                vals[k] = input_polynomial(self.u0[k], self.d1[k], self.d2[k], dt)
            if self.check(self.set_inputs(self.in_vr, me.n_in, vals), 11):
                return ERROR
        if me.n:
            buf = self.xbuf
            buf[:] = x
            if self.check(self.set_states(buf, me.n), 2):
                return ERROR
        return OK

    def _rhs(self, t: float, x, dxdt) -> None:
        """f(t, x) for the Runge-Kutta pair; NaN where the FMU cannot
        evaluate it (Discard: the pair takes a shorter step; worse: the
        step fails, and the pair is stopped by NaN)."""
        me = self.me
        if not me.failed_call and self._set_point(t, x) == OK:
            me.rhs += 1
            st = self.get_derivatives(self.dx, me.n)
            if st <= WARNING:
                dxdt[:] = self.dx
                return
            if st > DISCARD:
                self._failed(3, st)
        for i in range(me.n):
            dxdt[i] = math.nan

    def _cvode_rhs(self, t, y, ydot, user_data) -> int:
        """CVode's right-hand side: 0, 1 (recoverable: Discard) or -1."""
        me = self.me
        sun = self.cv.sun
        if me.failed_call:
            return -1
        if self._set_point(t, sun.N_VGetArrayPointer(y)[:me.n]) != OK:
            return -1
        me.rhs += 1
        st = self.get_derivatives(sun.N_VGetArrayPointer(ydot), me.n)
        if st <= WARNING:
            return 0
        if st == DISCARD:
            return 1
        self._failed(3, st)
        return -1

    def _indicators_at(self, t: float, x) -> list[float] | None:
        """The event indicators at (t, x), or None when the FMU failed."""
        if self._set_point(t, x) != OK:
            return None
        return self._read_indicators()

    def _read_indicators(self) -> list[float] | None:
        me = self.me
        if self.check(self.get_indicators(self.z, me.nz), 4):
            return None
        return self.z[:me.nz]

    # -- events ----------------------------------------------------------------

    def settle(self, kind: str | None) -> int:
        """In event mode: update the discrete states until they settle, then
        (unless the FMU ended the simulation) continuous-time mode with the
        new states, nominals, next event time and indicators. `kind` names
        the counter of the event (None at the end of initialization)."""
        me = self.me
        values_changed = nominals_changed = False
        for _ in range(MAX_EVENT_ITERATIONS):
            st, need, term, nominals, values, defined, next_time = self.update()
            if self.check(st, 7):
                return ERROR
            values_changed = values_changed or values
            nominals_changed = nominals_changed or nominals
            if term:
                me.terminated = 1
                break
            if not need:
                break
        else:
            return self._failed(FAIL_SETTLE, ERROR)
        if kind is not None:
            setattr(me, kind, getattr(me, kind) + 1)
        me.restart = 1
        if me.terminated:
            me.end_time = me.time
            return OK
        me.next_event_time = next_time if defined else math.inf
        if self.check(self.enter_continuous(), 8):
            return ERROR
        me.mode = CONTINUOUS
        if values_changed and me.n and self.check(self.get_states(self.x, me.n), 9):
            return ERROR
        if nominals_changed and me.n and self.read_nominals() != OK:
            return ERROR
        if me.nz:
            z = self._read_indicators()
            if z is None:
                return ERROR
            self.z_prev[:] = z
        return OK

    def read_nominals(self) -> int:
        """The states' nominal values: the absolute tolerances rtol |nominal|."""
        me = self.me
        if self.check(self.get_nominals(self.nominal, me.n), 10):
            return ERROR
        for i in range(me.n):
            nominal = abs(self.nominal[i])
            self.atolv[i] = me.rtol * (nominal if nominal > 0.0 else 1.0)
        return OK

    def _handle_event(self, kind: str) -> int:
        if self.check(self.enter_event(), 6):
            return ERROR
        self.me.mode = EVENT
        return self.settle(kind)

    def _completed(self) -> tuple[int, bool, bool]:
        """fmi2CompletedIntegratorStep where the FMU needs it: (status, enterEventMode, terminateSimulation)."""
        if not self.needs_completed:
            return OK, False, False
        st, enter, term = self.completed_step()
        if self.check(st, 5):
            return ERROR, False, False
        return OK, enter, term

    # -- after each accepted step ---------------------------------------------

    def _after_step(self, stiffness: float | None) -> int:
        """The FMU stands at the end of an accepted step: REACHED (go on),
        STATE (an indicator changed sign: its values in z_end), TERMINATE,
        STEP, STIFF or FAILED. `stiffness`: the pair's h |lambda|, or None."""
        me = self.me
        z = []
        if me.nz:
            z = self._read_indicators()
            if z is None:
                return FAILED
            z_prev = self.z_prev
            if any(crossed(z_prev[k], z[k]) for k in range(me.nz)):
                self.z_end[:me.nz] = z  # in place: the shared struct holds this array's address
                return STATE
        st, enter, term = self._completed()
        if st != OK:
            return FAILED
        if term:
            return TERMINATE
        if me.nz:
            self.z_prev[:] = z
        if enter:
            return STEP
        if stiffness is not None:
            if stiffness > STIFF_LIMIT[me.method]:
                me.nonstiff_count = 0
                me.stiff_count += 1
                if me.stiff_count >= STIFF_STEPS:
                    return STIFF
            else:
                me.nonstiff_count += 1
                if me.nonstiff_count >= NONSTIFF_RESET:
                    me.stiff_count = 0
        return REACHED

    def _locate(self, t0: float, t1: float, dense) -> tuple[float, list[float] | None] | None:
        """The earliest crossing inside the accepted step [t0, t1], on the
        dense output: (the first time found past it, its states, or None
        for the step's own end), to the event time tolerance; None when the
        FMU failed."""
        me = self.me
        z0, z1 = list(self.z_prev[:me.nz]), self.z_end
        h = t1 - t0
        lead = earliest([crossed(a, b) for a, b in zip(z0, z1)], z0, z1)
        search = Illinois(0.0, z0[lead], h, z1[lead])
        hi, z_lo = h, z0
        tol = max(me.event_time_tolerance, 4 * math.ulp(abs(t0) + h))
        trials = 0
        widths = [math.inf] * SAFEGUARD_TRIALS  # the bracket before each of the last trials
        while hi - search.lo > tol:
            width = hi - search.lo
            trial = search.next()
            # Safeguard: where the last trials did not halve the bracket (an
            # indicator that starts at zero after an event makes the secant
            # crawl), bisect.
            if not (search.lo < trial < hi) or width > 0.5 * widths[0]:
                trial = 0.5 * (search.lo + hi)
            widths = widths[1:] + [width]
            z = self._indicators_at(t0 + trial, dense(t0 + trial))
            if z is None:
                return None
            me.event_iterations += 1
            trials += 1
            now = [crossed(a, b) for a, b in zip(z0, z)]
            if any(now):
                if not now[lead]:
                    lead = earliest(now, z_lo, z)
                    search = Illinois(search.lo, z_lo[lead], trial, z[lead])
                else:
                    search.update(trial, z[lead], True)
                hi = trial
            else:
                search.update(trial, z[lead], False)
                z_lo = z
            if trials > MAX_TRIALS:
                self._failed(FAIL_LOCATE, ERROR)
                return None
        if hi == h:
            return t1, None
        return t0 + hi, dense(t0 + hi)

    def _end_integration(self, reason: int, t0: float, t1: float, x1, dense) -> int:
        """Take the integration's end (t1, x1) and handle what ended it; OK or a failure status."""
        me = self.me
        if reason == FAILED:
            return me.failed_status
        if reason == STATE:
            found = self._locate(t0, t1, dense)
            if found is None:
                return me.failed_status
            t_event, x_event = found
            me.time = t_event
            if me.n:
                self.x[:] = x1 if x_event is None else x_event
            if self._set_point(me.time, self.x[:me.n]) != OK:
                return ERROR
            st, _, term = self._completed()
            if st != OK:
                return ERROR
            if term:
                me.terminated = 1
                me.end_time = me.time
                return OK
            return self._handle_event("state_events")
        me.time = t1
        if me.n:
            self.x[:] = x1
        if reason == STEP:
            return self._handle_event("step_events")
        if reason == TERMINATE:
            me.terminated = 1
            me.end_time = me.time
        elif reason == STIFF:
            me.method = CVODE
            me.switches += 1
            me.restart = 1
        return OK

    # -- the integrators -----------------------------------------------------

    def _integrate(self, t_stop: float) -> int:
        """From the wrapper's time to t_stop, or to the first event before it."""
        me = self.me
        if not me.n:
            return self._integrate_without_states(t_stop)
        if me.method == CVODE:
            return self._integrate_cvode(t_stop)
        return self._integrate_rk(t_stop)

    def _integrate_without_states(self, t_stop: float) -> int:
        """No continuous states: time moves on in one step."""
        me = self.me
        t0 = me.time
        if self._set_point(t_stop, []) != OK:
            return ERROR
        me.steps += 1
        reason = self._after_step(None)
        return self._end_integration(reason, t0, t_stop, [], lambda t: [])

    def _integrate_rk(self, t_stop: float) -> int:
        me = self.me
        rk = self.rk
        rk.method, rk.rtol, rk.atolv = me.method, me.rtol, self.atolv[:me.n]
        rk.stiffness_test = me.solver == AUTO
        rk.n_accepted = rk.n_rejected = rk.n_rhs = 0
        reason = [REACHED]

        def observe(r) -> bool:
            reason[0] = self._after_step(r.h_lambda if r.stiffness_test else None)
            return reason[0] != REACHED

        x = self.x[:me.n]
        result, t1, me.h_next = rk.advance(self._rhs, me.time, t_stop, x, me.h_next, observe)
        me.steps += rk.n_accepted
        me.rejected += rk.n_rejected
        if me.failed_call:
            return me.failed_status
        if result not in (rkmod.OK, rkmod.STOPPED):
            me.err_t = t1
            me.failed_detail = result
            return self._failed(FAIL_RK, ERROR)
        return self._end_integration(reason[0], rk.t0, t1, x, rk.dense)

    def _integrate_cvode(self, t_stop: float) -> int:
        me = self.me
        if self.cv is None:
            self.cv = cvode.CVodeRun(me, self._cvode_rhs)
        cv = self.cv
        x = self.x[:me.n]
        if me.cv_owner != 1:
            flag = cv.create(me.time, x, self.atolv[:me.n])
            me.cv_owner = 1
        elif me.restart:
            flag = cv.reinit(me.time, x, self.atolv[:me.n])
        else:
            flag = 0
        me.restart = 0
        if flag:
            me.failed_detail = flag
            return self._failed(FAIL_CVODE, ERROR)
        failures0 = cv.failures()
        reason = REACHED
        t0 = t1 = me.time
        x1 = x
        for _ in range(MAX_CVODE_STEPS):
            flag, t1 = cv.step(t_stop)
            if me.failed_call:
                break
            if flag < 0:
                me.err_t = me.time
                me.failed_detail = flag
                self._failed(FAIL_CVODE, ERROR)
                break
            me.steps += 1
            x1 = cv.get(me.cv_y)
            if self._set_point(t1, x1) != OK:
                reason = FAILED
                break
            reason = self._after_step(None)
            if reason != REACHED or t1 >= t_stop:
                break
            me.time = t1
            self.x[:] = x1
            t0 = t1
        else:
            me.failed_detail = 0
            self._failed(FAIL_CVODE, ERROR)
        me.rejected += cv.failures() - failures0
        if me.failed_call:
            return me.failed_status
        return self._end_integration(reason, t0, t1, x1, cv.dense)

    # -- the communication step ------------------------------------------------

    def do_step(self, comp, t: float, h: float, no_set_prior: int = 0) -> int:
        """Integrate from t to t + h (fmi2DoStep's shape), through every event."""
        me = self.me
        me.failed_call = 0
        if me.terminated:
            return DISCARD
        if t != me.time or me.mode != CONTINUOUS:
            return self._failed(FAIL_TIME, ERROR)
        end = t + h
        if me.nz and me.inputs_dirty:
            # Inputs that jumped at this communication point may have crossed an indicator.
            z = self._read_indicators()
            if z is None:
                return ERROR
            if any(crossed(a, b) for a, b in zip(self.z_prev[:me.nz], z)):
                st = self._handle_event("input_events")
                if st != OK:
                    return st
            else:
                self.z_prev[:] = z
        me.inputs_dirty = 0
        at_once = 0
        while not me.terminated:
            if me.next_event_time <= me.time:
                at_once += 1
                if at_once > MAX_EVENT_ITERATIONS:
                    return self._failed(FAIL_TIME_EVENTS, ERROR)
                st = self._handle_event("time_events")
                if st != OK:
                    return st
                continue
            if me.time >= end:
                break
            at_once = 0
            st = self._integrate(end if me.next_event_time > end else me.next_event_time)
            if st != OK:
                return st
        if me.terminated:
            return OK if me.end_time >= end else DISCARD
        # The FMU at the step's end, where the master reads its outputs.
        return OK if self._set_point(me.time, self.x[:me.n]) == OK else ERROR
