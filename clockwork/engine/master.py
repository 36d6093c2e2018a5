"""The co-simulation master: the stepping loop.

A communication step from t to t + h (``advance``):

1. feedthrough-only instances (escapements, drag) call fmi2DoStep while
   their inputs still hold the values at t: they commit the discrete mode
   decided at t; their event indicators are read (z at t+);
2. dynamic instances (pendulum, vibration, averaged model) step, in
   Gauss-Seidel order (each sees the newest outputs of those before it) or
   in Jacobi order (all see the values at t), their inputs given by the
   coupling (zero-order hold, or polynomials of order 1 or 2);
3. outputs are updated at t + h in the dependency order of the
   ModelStructure, which also gives the event indicators z at t + h;
   only those of instances that allow a read after a set without a step
   (``Instance.outputs_after_inputs``; FMI 2.0 4.2.4, FMI 3.0 Step Mode):
   the others are stepped as dynamic ones and keep what their step gave
   (engine/wiring.py).

Around it, ``step`` adds what makes the result accurate:

1. the step is capped by the time scale of the event indicators' sources;
2. a checkpoint is taken when the step may need a rollback (an indicator
   is near zero, strong coupling, step doubling);
3. the step is taken: plainly, iterated to a fixed point of the coupling
   (``coupling.iterate_step``) or by step doubling (``richardson``);
4. when an indicator changed sign (or two crossings hide inside the step),
   the step is shortened to land just past the earliest crossing
   (``location``); a step that was predicted free of events and taken
   without a checkpoint is first replayed from the last one
   (``checkpoints``);
5. the outputs are checked for NaN, infinities and divergence.

``run_until`` steps on the drift-free grid start + k * step.
"""

from __future__ import annotations

import math
from ctypes import c_double, c_uint

from .checkpoints import Checkpoints
from ..fmi.description import REAL_TYPES, no_state_reason
from .coupling import InputCoupling, iterate_step
from ..fmi.calls import DISCARD, NO_MESSAGE, WARNING, free_all
from ..fmi.contract import Instance
from .events import crossed, earliest
from .location import APPROACH, LAND, EventLocator, scan
from .marks import Marks
from .parallel import updates_after
from .ports import Port, Ports
from .richardson import StepDoubling
from .samples import FileInputs, Samples, isclose
from .settings import MasterSettings, Statistics, check_run, rollback_need, with_model_exchange
from ..errors import SceneError, SimulationEnded, SimulationError, UsageError
from .wiring import Link, build


class Master:
    """The stepping loop over a set of wired FMU instances: the Python
    reference; ``CompiledMaster`` (engine/compiled.py) runs the same
    algorithm in C, with the same methods and the same bits.

    A `System` builds and initializes one (``System.master``); its public
    methods raise `ClosedError` once the System is freed.

    Attributes:
        t: The current communication point, s.
        start_time: Where the run started, s (the grid is
            ``start_time + k * settings.step``).
        settings: The `MasterSettings` it runs.
        stats: Counts of the run (``Statistics``): steps, events, rollbacks,
            replays, saved states, rejected steps, coupling and loop
            iterations.
        engine: ``"python"`` or ``"compiled"``.
        engine_reason: Why ``engine = "auto"`` chose the Python loop, or None.
        ended: None, or the `SimulationEnded` of an FMU that ended the
            simulation (then the run stopped cleanly at its last
            communication point).
    """

    MAX_REPLAY_STEPS = 64  # a forced checkpoint after this many steps bounds replay work and memory
    engine = "python"

    def __init__(self, instances: dict[str, Instance], links: list[Link],
                 settings: MasterSettings, start_time: float = 0.0,
                 step_order: list[str] | None = None,
                 extra_outputs: dict[str, list[str]] | None = None,
                 inputs: Samples | None = None, rates: dict[str, int] | None = None):
        self.instances = instances
        self.settings = settings
        self._multirate = None
        if rates is not None:
            rates = _slow_read_after_step(rates, instances)
        # Instances with counts of their own (the Model Exchange wrapper's
        # integrator), which join the master's (stats.model_exchange).
        self._own_counts = [inst for inst in instances.values() if inst.statistics() is not None]
        settings.check()
        self.wiring = build(instances, links, step_order, settings.algebraic_loops)
        # Inputs driven from samples (an input file): set at every step.
        self.file_inputs = None if inputs is None else FileInputs(
            inputs, instances, {(k.dst, k.input) for k in links})
        self.t = start_time  # the current communication point, s
        self.start_time = start_time
        self.stats = Statistics()
        self.ports = Ports(instances, self.wiring.links, self.wiring, extra_outputs, settings.event_location, self)
        self.discrete_outputs = self.ports.discrete_outputs
        self.coupling = InputCoupling(self.ports.dynamic, settings.extrapolation)
        for inst in instances.values():  # what an instance changed of its own setup (cs3: Event Mode refused)
            if inst.instantiation_note:
                self.coupling.note(inst.instantiation_note)
        for loop in self.ports.loops:
            if loop.solve_in_init:
                held = [p.inst for p in loop.members if not p.inst.outputs_after_inputs]
                self.coupling.note(
                    f"algebraic loop {loop.name}: {', '.join(i.name for i in held)} do"
                    f"{'es' * (len(held) == 1)} not allow outputs to be read after inputs are set without a step "
                    "(FMI 2.0 4.2.4, FMI 3.0 Step Mode): solved in Initialization Mode, then broken by a one-step "
                    "delay in the steps", kind="note")
        self._updates_after = updates_after(self.ports)  # per dynamic instance (engine/parallel.py)
        self.locator = EventLocator(self, self.ports.all)
        self.checkpoints = Checkpoints(self)
        self.doubling = StepDoubling(self)
        self.on_step = None  # optional callback(master) after each accepted step
        # True right after a discontinuity (the start, an event, a changed
        # parameter): inputs restart from zero-order hold, the next step
        # checks its indicators.
        self.after_event = True
        self.after_event_step = False  # the step now being taken ended at an event
        self._needs_rollback = settings.iterations > 0 or settings.richardson
        self._locating = bool(settings.event_location and self.locator.active)
        self._predicting = self._locating and settings.event_prediction and self.locator.has_sources
        self._extrapolating = bool(settings.extrapolation)
        self._jacobi = settings.order == "jacobi"
        self._check_rollback()
        self._check_polynomial_inputs()
        if settings.threads > 1 and self.engine == "python":
            self.coupling.note(f"master.threads = {settings.threads}: the Python engine steps one instance at a "
                               "time (its FMI calls hold Python's global lock); the compiled core uses the threads")
        # The instances' announced time events (the contract's time_events,
        # e.g. cs3._Events): a communication point lands on each.
        self.time_events = [p.inst.time_events for p in self.ports.all if p.inst.time_events is not None]
        self._reset_soft_state()
        self.engine_reason: str | None = None  # why "auto" chose this engine, when not the core
        self.ended: SimulationEnded | None = None  # an FMU ended the simulation (a clean end)
        self._frees_seen = -1  # Instance.frees when run_until last found every instance alive
        if rates is not None:  # components at their own steps (engine/multirate.py); else today's path
            self._multirate = _multirate(self, rates)
            self.step = self._multirate.step

    def __reduce_ex__(self, protocol):
        raise UsageError("a master cannot be pickled or copied: it holds loaded FMU libraries and their "
                         "instances' C state; build a System in the other process")

    @property
    def stats(self) -> Statistics:
        return with_model_exchange(self._stats, self._own_counts)

    @stats.setter
    def stats(self, value: Statistics) -> None:
        self._stats = value

    @property
    def notes(self) -> list[str]:
        """What the master changed of the settings, said once each (e.g. a lowered extrapolation order)."""
        return self.coupling.notes

    def count_loop(self, iterations: int, fallbacks: int) -> None:
        """Algebraic loops (loops.Loop) count their iterations and fallbacks here."""
        self.stats.loop_iterations += iterations
        self.stats.loop_fallbacks += fallbacks

    def _check_rollback(self) -> None:
        """A rollback needs every FMU's state: refuse before the first step."""
        need = rollback_need(self.settings, self.locator.active)
        if need is None:
            return
        key, why = need
        for inst in self.instances.values():
            if not inst.can_get_set_state:
                raise SceneError(f"{key}: {inst.name} ({inst.path.name}) cannot save and restore its state "
                                 f"({no_state_reason(inst.md)}), and {why} rolls every FMU back")

    def _check_polynomial_inputs(self) -> None:
        """Refuse inputs given as polynomials (extrapolation, or strong
        coupling's lines between iterates) into an instance that refuses
        them (an FMI 3.0 FMU without intermediate update: its
        Co-Simulation interface takes no input derivatives), before the
        first step."""
        s = self.settings
        if s.extrapolation:
            key, value, fix = "master.extrapolation", s.extrapolation, "master.extrapolation = 0"
        elif s.iterations > 0:
            key, value, fix = "master.iterations", s.iterations, "master.iterations = 0"
        else:
            return
        summed = next((p for p in self.ports.dynamic if p.adds), None)
        if summed is not None:  # the polynomials go through each input's one source (coupling.py)
            raise SceneError(f"{key} = {value}: not supported with a sum into {summed.inst.name}."
                             f"{summed.in_names[summed.adds[0][0]]} (an OSP Sum); use {fix}")
        for p in self.ports.dynamic:
            refusal = p.inst.polynomial_inputs_refusal(fix) if p.n_in else None
            if refusal:
                raise SceneError(f"{key} = {value}: {p.inst.name} ({p.inst.path.name}) {refusal}")

    # -- initialization --------------------------------------------------

    def initialize(self, parameters: dict[str, dict[str, object]]) -> None:
        """Set up every instance, resolve the initial outputs, leave init mode."""
        ports = self.ports
        self.ended = None
        if self._multirate is not None:
            self._multirate.detach()  # in Initialization Mode every value passes at once
        for name, inst in self.instances.items():
            inst.setup(self.start_time, parameters.get(name, {}), self.settings.tolerance)
        if self.file_inputs is not None:
            self.file_inputs.set(ports.all, self.start_time, False)
        # Outputs in initialization mode follow from parameters; two sweeps
        # settle feedthrough chains of any depth found in these scenes.
        # An algebraic loop (engine/loops.py) reads outputs of the last run
        # before they are read again: forgotten, as in a new master. A loop
        # broken by a delay starts in the second sweep, once every output
        # feeding it has been read.
        ports.forget_outputs()
        ports.initializing(True)
        for sweep in range(2):
            if sweep == 1:
                ports.start_loops()
            ports.propagate(ports.order, self.t)
        ports.initializing(False)
        for inst in self.instances.values():
            inst.exit_init()
        # Outputs after Initialization Mode: an instance that does not allow a
        # read after a set (FMI 2.0 4.2.4, FMI 3.0 Step Mode) is only read.
        ports.after_init(self.t)
        self.coupling.find_derivative_sources()
        self.t = self.start_time
        # The start is a communication point like any other: its outputs are
        # checked as each step's are (5. in run_until), so that a NaN there
        # fails the run at the start time with no point recorded (the
        # history holds legal numbers only), not at the end of the first step.
        if ports.diverged(self.settings.divergence_limit):
            ports.name_divergence(self.t, self.settings.divergence_limit, last_point=None)
        self._start()
        if self._multirate is not None:
            self._multirate.start()

    def _start(self) -> None:
        """The master's own state at the start: the past forgotten, the
        indicators read, their sources sampled."""
        self._reset_soft_state()
        loc = self.locator
        loc.z_end = loc.indicators()
        if loc.has_sources:
            # The sources' time scale caps the very first step too (a first
            # step over several crossings would hide them). When the start
            # says nothing (at rest at zero), the first step is short instead.
            loc.remember_sources()
            if loc.step_cap == math.inf:
                loc.sources_prev = None

    def reinitialize(self, parameters: dict[str, dict[str, object]]) -> None:
        """fmi2Reset every instance and initialize again (shooting uses this)."""
        for inst in self.instances.values():
            inst.reset()
        self.initialize(parameters)

    def restart(self, parameters: dict[str, dict[str, object]]) -> None:
        """A new run on the same instances: reinitialize, with the counts
        and the per-step callback of the last run forgotten."""
        self.on_step = None
        self.stats = Statistics()
        self.reinitialize(parameters)

    def discontinuity(self) -> None:
        """Tell the master that something changed outside the wiring at this
        communication point (a tunable parameter, an unconnected input): the
        input polynomials restart from zero-order hold, finite differences
        forget the past, and the next step takes a fresh checkpoint so that a
        replay never reaches back across the change."""
        self.after_event = True
        self.locator.time_to_zero = 0.0
        self.coupling.forget()
        self.record_history()

    def _reset_soft_state(self) -> None:
        self.coupling.forget()
        self.checkpoints.reset()
        self.after_event = True
        self.locator.reset()
        self.record_history()

    def record_history(self) -> None:
        self.coupling.record(self.t, self.after_event_step or self.after_event)

    # -- the communication step ----------------------------------------

    def advance(self, t: float, h: float, coupling: dict | None = None) -> None:
        """One communication step from t to t + h of every instance.

        `coupling` (strong coupling): per instance, the inputs at the
        step's start and at its end from the last iterate.
        """
        t_new = t + h
        ports = self.ports
        loc = self.locator
        no_set_prior = 0 if self.checkpoints.held else 1  # noSetFMUStatePriorToCurrentPoint
        inputs = self.file_inputs
        if inputs is not None:  # sampled inputs at t, after an event there
            inputs.set(ports.all, t, True)
        self._commit_first(t, h, no_set_prior)
        # 2. Dynamic instances step, their inputs set by the coupling.
        set_inputs = self.coupling.set_inputs
        smooth = not self.after_event
        jacobi = self._jacobi
        dynamic = ports.dynamic
        if jacobi:
            for p in dynamic:
                if p.has_inputs:
                    set_inputs(p, t, h, smooth, coupling.get(p.inst.name) if coupling else None)
        last = dynamic[-1] if dynamic else None
        for p, after in zip(dynamic, self._updates_after):
            if not jacobi and p.has_inputs:
                set_inputs(p, t, h, smooth, coupling.get(p.inst.name) if coupling else None)
            st = p.doStep(p.comp, t, h, no_set_prior)
            if st > WARNING:
                raise self._step_failure(p, st, t, h)
            if inputs is not None:
                inputs.set((p,), t_new, False, True)
            p.read(t_new)
            if not jacobi and p is not last:
                # Newest values flow on to the instances stepped later
                # (through the feedthrough-only instances they reach).
                ports.propagate(after, t_new)
        # 3. Outputs at t + h, in dependency order.
        self.t = t_new
        for p in ports.final_order:
            p.pull(t_new)
        if self._locating:
            loc.z_end = loc.indicators()

    def _commit_first(self, t: float, h: float, no_set_prior: int) -> None:
        """1. of the step from t of h s: feedthrough-only instances commit
        the mode decided at t; the indicators at t+ are taken."""
        inputs = self.file_inputs
        loc = self.locator
        for p in self.ports.first:
            st = p.doStep(p.comp, t, h, no_set_prior)
            if st > WARNING:
                raise self._step_failure(p, st, t, h)
            if p.z_pos and self.after_event:
                # A commit may have switched the mode: read z at t+.
                p.getReal(p.comp, p.out_vr, p.n_out, p.out)
        if inputs is not None:  # their outputs are next read at t + h: sampled inputs there, before an event
            inputs.set(self.ports.first, t + h, False, True)
        if self._locating:
            # Without a commit of a new mode, z at t+ is z at t.
            loc.z_start = loc.indicators() if self.after_event else loc.z_end

    def _asked_to_end(self) -> SimulationEnded | None:
        """The end an instance asked for in a step it finished (announced in
        its time_events: FMI 3.0's terminateSimulation), else None."""
        for p in self.ports.all:
            end = p.inst.ended(self.t) if p.inst.time_events is not None else None
            if end is not None:
                return end
        return None

    @staticmethod
    def _step_failure(p: Port, st: int, t: float, h: float) -> SimulationError:
        """The error for a failed step; SimulationEnded where the FMU ended
        the simulation (a clean end, caught by run_until)."""
        inst = p.inst
        if st == DISCARD:
            end = inst.ended(t, h)
            if end is not None:
                return end
            return SimulationError(
                f"{inst.name}: {inst.named('doStep')} from t = {t!r} s with h = {h!r} s was discarded: "
                f"{inst.last_message() or NO_MESSAGE}", time=t, instance=inst.name)
        return inst.fail(f"{inst.named('doStep')}({t!r}, {h!r})", st, t)

    # -- the accurate step ---------------------------------------------

    def step(self, h: float) -> float:
        """Advance by at most h (less when an event is located). Returns the step taken, s.

        One communication step from ``t``, with everything of the settings
        that makes it accurate (event location, rollback, strong coupling,
        step doubling). `run_until` is the usual way to step.

        Args:
            h: The largest step to take, s (> 0).

        Raises:
            SimulationError: An FMU failed, or an output is NaN, infinite or
                beyond ``divergence_limit``.
            SimulationEnded: An FMU ended the simulation (`run_until`
                catches it into ``ended``).
        """
        s = self.settings
        t = self.t
        loc = self.locator
        # 0. An instance that asked to end the simulation in a step it
        # finished ends it here; its announced time event caps the step.
        for ev in self.time_events:
            if ev.terminated:
                raise self._asked_to_end()
            if t < ev.next_event_time < t + h:
                h = ev.next_event_time - t
        # A sampled input's event is a discontinuity at the step's start
        # and ends a step that would pass it.
        if self.file_inputs is not None:
            samples = self.file_inputs.samples
            if samples.event_at(t):
                self.discontinuity()
            te = samples.next_event(t)
            if t + h > te and not isclose(t + h, te):
                h = te - t
        # 1. The indicators' sources cap the step.
        if loc.has_sources:
            if loc.sources_prev is None:
                h *= 1.0 / 64  # no time scale known yet: a short first step
            elif h > loc.step_cap:
                h = loc.step_cap
        self.after_event_step = False
        # 2. A checkpoint where the step may need a rollback. Could an
        # indicator reach zero in this step? Conservative: at 4x the last
        # step's rate of change. Where the crossing can be predicted, the
        # step is shortened to land on it (or clear of it) instead, and needs
        # no checkpoint: a miss is replayed from the last one. A checkpoint
        # also bounds how far back a replay must go.
        needs_rollback = self._needs_rollback
        locating = self._locating
        near = locating and (self.after_event or loc.time_to_zero <= 4.0 * h)
        predicted = 0
        if self._predicting:
            if self.after_event or loc.time_to_zero <= 16.0 * h:
                loc.sample(t)
            if near and not self.after_event:
                plan = loc.plan(t, h)
                if plan is not None:
                    predicted, h = plan
        possible = (near and not predicted) or (locating and len(self.checkpoints.since) >= self.MAX_REPLAY_STEPS)
        if near and loc.stale_sources:
            # The hidden-crossing check needs the sources at the step start.
            loc.remember_sources()
            loc.stale_sources = False
        if possible or needs_rollback:
            self.checkpoints.take()
        # 3. The step. One that lands past a predicted crossing is taken as
        # locate takes its trials: plainly (an iterate or a half step would
        # see the switched mode at its end and spread it over the step).
        if not needs_rollback or predicted == LAND:
            self.advance(t, h)
        elif s.richardson:
            h = self.doubling.step(t, h)
        else:
            iterate_step(self, t, h)
        taken = h
        # 4. Events.
        if locating:
            taken = self._land_on_events(t, h, near and not predicted, possible or needs_rollback, predicted)
            if self.after_event_step and self._multirate is not None:
                self._multirate.land()  # the components of other rates to the event, too
            loc.last_step = None if self.after_event_step else (t, loc.z_start)
        if loc.has_sources:
            # Sources are sampled where a crossing is near, and now and then
            # to keep the time-scale estimate behind the step cap fresh.
            loc.sample_countdown -= 1
            if near or loc.sample_countdown <= 0 or loc.sources_prev is None:
                loc.remember_sources()
                loc.sample_countdown = 16
                loc.stale_sources = False
            else:
                loc.stale_sources = True
        self.after_event = self.after_event_step
        self.stats.steps += 1
        # 5. NaN, infinities, divergence.
        if self.ports.diverged(s.divergence_limit):
            self.ports.name_divergence(self.t, s.divergence_limit, last_point=t)
        if self._extrapolating:
            self.record_history()
        if self.on_step is not None:
            self.on_step(self)
        return taken

    def _land_on_events(self, t: float, h: float, near: bool, checkpointed: bool, predicted: int = 0) -> float:
        """After the step from t of h s: when an indicator crossed zero, land
        just past the earliest crossing instead (unless the step already
        did, as a predicted landing does). Returns the step taken, s."""
        loc = self.locator
        z0, z1 = loc.z_start, loc.z_end
        time_to_zero = scan(z0, z1, h)
        hit = time_to_zero < 0.0
        if not hit and near and loc.has_sources:
            hidden = loc.hidden_crossing(h, z0, z1)
            if hidden is not None:
                # Two crossings inside one step cancel at its ends; try the
                # step up to the interpolant's extremum (near: checkpointed).
                self.checkpoints.rollback()
                self.advance(t, hidden)
                self.stats.event_iterations += 1
                z0, z1 = loc.z_start, loc.z_end
                time_to_zero = scan(z0, z1, hidden)
                hit = time_to_zero < 0.0
                if hit:
                    h = hidden
                else:  # the interpolant was wrong: redo the whole step
                    self.checkpoints.rollback()
                    self.advance(t, h)
                    z0, z1 = loc.z_start, loc.z_end
                    time_to_zero = scan(z0, z1, h)
        if not hit:
            loc.time_to_zero = time_to_zero
            self.checkpoints.since.append(h)
            return h
        crossings = [crossed(a, b) for a, b in zip(z0, z1)]
        z0, z1 = list(z0), list(z1)
        s = self.settings
        lead = earliest(crossings, z0, z1)
        if abs(z1[lead]) <= s.event_indicator_tolerance or h <= loc.time_tolerance(t, h):
            # Already just past the crossing, where locate would stop at once.
            if predicted == LAND:
                self.stats.predicted_landings += 1
            self.stats.events += 1
            loc.located_from = t
            self.after_event_step = True
            loc.time_to_zero = 0.0
            self.checkpoints.since.append(h)
            return h
        if predicted:
            self.stats.mispredicted += 1
        if not checkpointed:
            # An event in a step predicted free of them: back to the last
            # checkpoint, replay to t, and take the step again from there.
            self.checkpoints.replay_to(t)
            self.advance(t, h)
        taken = loc.locate(t, h, crossings, z0, z1)
        self.after_event_step = True
        loc.time_to_zero = 0.0
        self.checkpoints.since.append(self.t - loc.located_from)
        return taken

    # -- running ----------------------------------------------------------

    def run_until(self, t_stop: float, on_point=None) -> None:
        """Step to t_stop on the grid start + k*step, plus located events.

        Grid points are computed as start + k*step, never by summing steps,
        so that time does not drift. An FMU that ends the simulation ends
        the run cleanly at the last communication point: ``ended`` says
        when and which, and later calls return at once. Called again with a
        later time, it goes on from where it stopped.

        Args:
            t_stop: Where to stop, s: finite and not before ``t``.
            on_point (Callable[[Master], None] | None): Called as
                ``on_point(master)`` at every communication point reached
                (grid points and located events), or None.

        Raises:
            UsageError: ``t_stop`` NaN, infinite, not a number or before the
                current time.
            ClosedError: The System was freed.
            SimulationError: An FMU failed (with its own message), or an
                output became NaN, infinite or diverged; the message names
                the time, the instance and the variable.
        """
        frees = Instance.frees
        t_stop = check_run(self.instances, self.t, t_stop, look=frees != self._frees_seen)
        self._frees_seen = frees
        if self.ended is not None:
            return
        try:
            self._run_until(t_stop, on_point)
        except SimulationEnded as e:
            self.ended = e

    def _run_until(self, t_stop: float, on_point=None) -> None:
        s = self.settings
        h_nom, t0 = s.step, self.start_time
        eps = 1e-12 * max(1.0, abs(t_stop))
        k = math.floor((self.t - t0) / h_nom + 1e-9) + 1
        step = self.step
        doubling = self.doubling
        while self.t < t_stop - eps:
            grid = t0 + k * h_nom
            if grid > t_stop:
                grid = t_stop
            if s.richardson and doubling.next_step is not None:
                grid = min(self.t + max(doubling.next_step, s.min_step), t_stop)
            h = grid - self.t
            if h <= eps:
                k += 1
                continue
            step(h)
            if on_point is not None:
                on_point(self)
            if self.t >= grid - eps:
                k += 1

    def run_marks(self, t_stop: float, marks: Marks, on_rows=None) -> bool:
        """Step toward t_stop through the `marks`' communication points,
        recording their rows (engine/marks.py says what a plan holds).

        Called again with the same plan (a later stop, or after a stop at a
        change) it goes on where it stopped. An FMU that ends the simulation
        ends the run cleanly, as in `run_until` (``ended``).

        Args:
            t_stop: Where to stop, s: finite and not before ``t``.
            marks: The plan (`Marks`); it keeps its place across calls.
            on_rows (Callable[[list[tuple]], None] | None): Gets the rows in
                batches (of about ``marks.rows_per_call``, all of them before
                the call returns); None keeps them in ``marks.rows``.

        Returns:
            True where it returned at a watched output's change
            (``stop_at_change``), False at t_stop.
        """
        t_stop = check_run(self.instances, self.t, t_stop, call="run_marks")
        self._bind_marks(marks)
        stopped = False
        if self.ended is None:
            try:
                stopped = self._run_marks(t_stop, marks, on_rows)
            except SimulationEnded as e:
                self.ended = e
        if on_rows is not None and marks.rows:
            rows, marks.rows = marks.rows, []
            on_rows(rows)
        return stopped

    def _bind_marks(self, marks: Marks) -> None:
        """Refuse a plan whose ports or instances are not this master's."""
        if not isinstance(marks, Marks):
            raise UsageError(f"run_marks(marks = {type(marks).__name__}): expected a Marks plan "
                             "(clockwork.engine.marks.Marks)")
        if getattr(marks, "_bound", None) is self:
            return
        ports = {id(p) for p in self.ports.all}
        for where in ("outputs", "before", "watched"):
            for p, j in getattr(marks, where):
                if id(p) not in ports or not 0 <= j < p.n_out:
                    raise UsageError(f"run_marks: Marks({where}) holds ({p!r}, {j}), which is not an output "
                                     "position of one of this master's ports (master.ports[name])")
        port_of = {id(p.inst): p for p in self.ports.all}
        for inst, vr in marks.inputs:
            p = port_of.get(id(inst))
            if p is None:
                raise UsageError(f"run_marks: Marks(inputs) holds {inst!r}, which is not one of this master's "
                                 "instances")
            found = [v for v in inst.variables.values() if v.vr == vr and v.causality == "input" and not v.shape]
            if not found or found[0].type not in REAL_TYPES:
                raise UsageError(f"run_marks: Marks(inputs) holds ({inst.name}, {vr}): expected the value reference "
                                 f"of a Real input of {inst.name}")
            if found[0].name in p.in_names:
                raise UsageError(f"run_marks: Marks(inputs) holds {inst.name}.{found[0].name}, which is connected "
                                 "(the coupling sets it at every step): a mark sets unconnected inputs")
        marks._bound = self

    def _run_marks(self, t_stop: float, marks: Marks, on_rows) -> bool:
        eps = 1e-12 * max(1.0, abs(t_stop))
        tol = eps if marks.tolerance is None else marks.tolerance
        max_step = self.settings.step if marks.max_step is None else marks.max_step
        margin = marks.margin
        times, sets, values = marks.times, marks.sets, marks.values
        outputs, before, watched = marks.outputs, marks.before, marks.watched
        marks.start()
        seen, previous = marks.seen, marks.previous
        follow, period = marks.follow if marks.follow is not None else (-1, 0.0)
        rows, record, batch = marks.rows, marks.record_at_marks, marks.rows_per_call
        value = (c_double * 1)()
        setters = [(inst, inst.c_setReal, inst.component, (c_uint * 1)(vr), f"{inst.named('setReal')} of inputs")
                   for inst, vr in marks.inputs]

        def act(k: int) -> None:  # at mark k
            if sets[k]:
                value[0] = values[k]
                for inst, c_set, comp, vr, what in setters:
                    inst.check(c_set(comp, vr, 1, value), what, self.t)
            elif record:
                rows.append((self.t, *(p.out[j] for p, j in outputs), *previous))

        while True:
            # The marks reached (at the start, or passed by a step that was cut short).
            while marks.next < len(times) and not self.t < times[marks.next] - tol:
                act(marks.next)
                marks.next += 1
            if self.t >= t_stop - eps and (marks.next >= len(times) or times[marks.next] > t_stop):
                return False
            if before:
                previous[:] = [p.out[j] for p, j in before]
            k = marks.next
            target = times[k] if k < len(times) else (self.t + margin if margin is not None else t_stop)
            aim = target - self.t
            h = min(max_step, aim, t_stop - self.t)
            taken = self.step(h)
            if k < len(times) and h == aim and taken == h:  # a step aimed at the mark, taken whole
                act(k)
                marks.next += 1
            if any(p.out[j] != x for (p, j), x in zip(watched, seen)):
                seen[:] = [p.out[j] for p, j in watched]
                rows.append((self.t, *(p.out[j] for p, j in outputs), *previous))
                if follow >= 0:
                    tt = seen[follow]
                    if tt != marks.last_event:
                        if marks.last_event > 0:
                            marks.prev_event = marks.last_event
                        marks.last_event = tt
                        interval = tt - marks.prev_event if marks.prev_event is not None else period
                        times[:], sets[:], values[:] = [tt + interval + margin], [False], [0.0]
                        marks.next = 0
                if marks.stop_at_change:
                    return True
            if on_rows is not None and len(rows) >= batch:
                on_rows(rows[:])
                rows.clear()

    @property
    def rates(self) -> dict[str, int]:
        """{instance: its decimation factor}: how many base steps (master.step) each component's own step is."""
        k = self._multirate.k if self._multirate is not None else {}
        return {name: k.get(name, 1) for name in self.instances}

    def stop_threads(self) -> None:
        """Stop the threads master.threads started (the compiled core's); here, none."""

    def terminate(self) -> None:
        free_all(self.instances)


def _slow_read_after_step(rates: dict[str, int], instances: dict) -> dict[str, int] | None:
    """The checked rates, or None when every component steps at the base
    step. A slow component's outputs are read after its own steps only:
    the wiring steps it as a dynamic one (engine/wiring.py, ``strict``)."""
    from .multirate import check_rates
    rates = check_rates(rates, instances)
    for name, k in (rates or {}).items():
        if k != 1:
            instances[name].outputs_after_inputs = False
    return rates


def _multirate(master: Master, rates: dict[str, int]):
    """The multi-rate stepping of `master`, after the one-line refusals of
    what it does not do across rates (engine/multirate.py)."""
    from .multirate import MultiRate, TimedMultiRate, loop_problem, problem, timed
    indicators = {p.inst.name: p.z_pos for p in master.ports.all}
    links = [(src.inst.name, p.inst.name) for p in master.ports.all for _, src, _ in p.sources]
    links += [(src.inst.name, p.inst.name) for p in master.ports.all for src, _ in p.din_sources]
    found = problem(master.settings, rates, indicators, links)
    if found:
        raise SceneError(found[1], key="rates")
    loops = loop_problem(rates, [(loop.name, [p.inst.name for p in loop.members]) for loop in master.ports.loops])
    if loops:
        raise SceneError(loops, key="components")
    return (TimedMultiRate if timed(master.settings, rates, indicators) else MultiRate)(master, rates)

