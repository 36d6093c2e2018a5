"""The co-simulation master: the stepping loop.

One communication step from t to t + h reads like this (``_advance``):

1. feedthrough-only instances (escapements, drag) call fmi2DoStep while
   their inputs still hold the values at t: they commit the discrete mode
   decided at t; their event indicators are read (z at t+);
2. dynamic instances (pendulum, vibration, averaged model) step, in
   Gauss-Seidel order (each sees the newest outputs of those before it) or
   in Jacobi order (all see the values at t), their inputs extrapolated by
   polynomials of order 0, 1 or 2 through fmi2SetRealInputDerivatives;
3. outputs are updated at t + h in the dependency order of the
   ModelStructure, which also gives the event indicators z at t + h.

Around it, ``step`` adds what makes the result accurate:

- event location: when an indicator changes sign inside the step, every
  FMU is rolled back with fmi2SetFMUstate and the step is shortened by
  Illinois iteration until the crossing is bracketed to the time tolerance
  or the indicator is within its tolerance; the communication point is put
  just past the crossing, where the feedthrough FMU reads the new mode;
- optional strong coupling (fixed-point iteration of the step with the
  coupling inputs interpolated linearly over the step) and Richardson step
  doubling with step-size control.

FMU state is saved only when a step may need a rollback, into one reused
buffer per instance. When an event arrives in a step that was predicted
free of events, the master returns to its last checkpoint and replays the
(deterministic) steps since then.
"""

from __future__ import annotations

import math
from ctypes import c_double, c_int, c_uint
from dataclasses import dataclass, field

from .errors import SceneError, SimulationError
from .events import Illinois, hermite_extremum, hermite_root
from .fmu import DISCARD, WARNING, Instance
from .graph import Link, Wiring, build


_ORDER_ONE = (c_int * 1)(1)
_ORDER_TWO = (c_int * 1)(2)


@dataclass
class MasterSettings:
    step: float = 0.01  # nominal communication step, s
    order: str = "gauss-seidel"  # or "jacobi"
    extrapolation: int = 0  # order of the input polynomials: 0, 1, 2
    event_location: bool = True
    event_time_tolerance: float = 1e-10  # s
    event_indicator_tolerance: float = 1e-12  # in the indicator's unit (rad)
    iterations: int = 0  # strong coupling: fixed-point iterations per step (0 = off)
    iteration_tolerance: float = 1e-10
    richardson: bool = False
    richardson_tolerance: float = 1e-8
    min_step: float = 1e-9  # s
    max_step: float | None = None  # s; None = step
    divergence_limit: float = 1e8  # |output| beyond this counts as divergence


@dataclass
class Statistics:
    steps: int = 0
    events: int = 0
    event_iterations: int = 0
    rollbacks: int = 0
    replays: int = 0
    states_saved: int = 0
    rejected: int = 0
    coupling_iterations: int = 0


class _Port:
    """Preallocated ctypes arrays of one instance's connected variables."""

    def __init__(self, inst: Instance, inputs: list[str], outputs: list[str], indicators: list[str]):
        self.inst = inst
        self.comp = inst.component
        # Indicators come last (read twice if also an output), so that the
        # master takes them all with one slice of `out`.
        self.out_names = outputs + indicators
        self.n_out = len(self.out_names)
        self.out_vr = (c_uint * max(1, self.n_out))(*[inst.variables[n].vr for n in self.out_names])
        self.out = (c_double * max(1, self.n_out))()  # rebound by the Master into its one buffer
        self.z_pos = list(range(len(outputs), self.n_out))
        self.in_names = inputs
        self.n_in = len(inputs)
        self.in_vr = (c_uint * max(1, self.n_in))(*[inst.variables[n].vr for n in inputs])
        self.inp = (c_double * max(1, self.n_in))()
        self.der_vr = (c_uint * max(1, 2 * self.n_in))(*([inst.variables[n].vr for n in inputs] * 2))
        self.der_order = (c_int * max(1, 2 * self.n_in))(*([1] * self.n_in + [2] * self.n_in))
        self.der = (c_double * max(1, 2 * self.n_in))()
        # (input position, source port, source output position)
        self.sources: list[tuple[int, "_Port", int]] = []
        self.out_time = 0.0  # time at which `out` was read, s
        self.doStep, self.getReal, self.setReal = inst.c_doStep, inst.c_getReal, inst.c_setReal
        self.sent: list[float] = []  # inputs last given to the FMU (ZOH), to skip repeats
        self.sent_valid = False


@dataclass
class _History:
    """Recent values of dynamic inputs for finite-difference extrapolation."""

    times: list[float] = field(default_factory=list)
    values: list[list[float]] = field(default_factory=list)


class Master:
    def __init__(self, instances: dict[str, Instance], links: list[Link],
                 settings: MasterSettings, start_time: float = 0.0,
                 step_order: list[str] | None = None,
                 extra_outputs: dict[str, list[str]] | None = None):
        self.instances = instances
        self.settings = settings
        self.wiring: Wiring = build(instances, links, step_order)
        self.t = start_time
        self.start_time = start_time
        self.stats = Statistics()
        s = settings
        if s.order not in ("gauss-seidel", "jacobi"):
            raise SceneError(f"master.order = {s.order!r}: expected 'gauss-seidel' or 'jacobi'")
        if s.richardson and s.iterations > 0:
            raise SceneError("master.richardson and master.iterations cannot be combined: "
                             "step doubling does not iterate the coupling")
        if s.extrapolation not in (0, 1, 2):
            raise SceneError(f"master.extrapolation = {s.extrapolation}: expected 0, 1 or 2")

        inputs: dict[str, list[str]] = {n: [] for n in instances}
        outputs: dict[str, list[str]] = {n: [] for n in instances}
        for link in links:
            inputs[link.dst].append(link.input)
            if link.output not in outputs[link.src]:
                outputs[link.src].append(link.output)
        for link in links:
            for inst_name, var in ((link.src, link.output), (link.dst, link.input)):
                if instances[inst_name].variables[var].type != "Real":
                    raise SimulationError(
                        f"connection {link.src}.{link.output} -> {link.dst}.{link.input}: only Real "
                        f"connections are supported, {inst_name}.{var} is "
                        f"{instances[inst_name].variables[var].type}")
        # Integer and Boolean outputs are discrete: read on demand, not per step.
        self.discrete_outputs: dict[str, list[str]] = {n: [] for n in instances}
        for n, names in (extra_outputs or {}).items():
            for x in names:
                if instances[n].variables[x].type != "Real":
                    self.discrete_outputs[n].append(x)
                elif x not in outputs[n]:
                    outputs[n].append(x)
        indicators = {
            n: (inst.event_indicators if s.event_location else []) for n, inst in instances.items()
        }
        self.ports = {n: _Port(inst, inputs[n], outputs[n], indicators[n]) for n, inst in instances.items()}
        # All outputs live in one buffer: the divergence check is one pass.
        self._outputs = (c_double * sum(max(1, p.n_out) for p in self.ports.values()))()
        offset = 0
        for p in self.ports.values():
            n = max(1, p.n_out)
            p.out = (c_double * n).from_buffer(self._outputs, offset * 8)
            offset += n
        for link in links:
            dst, src = self.ports[link.dst], self.ports[link.src]
            dst.sources.append((dst.in_names.index(link.input), src, src.out_names.index(link.output)))

        w = self.wiring
        self._first = [self.ports[n] for n in w.feedthrough_only]
        self._dynamic = [self.ports[n] for n in w.dynamic]
        self._order = [self.ports[n] for n in w.evaluation_order]
        self._first_in_order = [p for p in self._order if p in self._first]
        self._indicator_ports = [p for p in self.ports.values() if p.z_pos]
        self._z_spans = [(p.z_pos[0], p.z_pos[-1] + 1, p.out) for p in self._indicator_ports]
        self._all = list(self.ports.values())
        self._history = {p.inst.name: _History() for p in self._dynamic}
        self._deriv_sources = self._derivative_sources() if s.extrapolation else {}
        self._z_start: list[float] = []
        self._z_end: list[float] = []
        # Time until the nearest indicator reaches zero at its last rate of
        # change, s; 0 = unknown (after an event), so the next step checks.
        self._time_to_zero = 0.0
        self.on_step = None  # optional callback(master) after each accepted step
        self._needs_rollback = s.iterations > 0 or s.richardson
        self._locating = bool(s.event_location and self._indicator_ports)
        self._extrapolating = bool(s.extrapolation)
        self._jacobi = s.order == "jacobi"
        self._z_sources = self._indicator_sources()
        self._z_sources_any = any(x is not None for x in self._z_sources)
        self._sample_countdown = 0
        self._rate_buffer = (c_double * 1)()
        self._reset_soft_state()
        # After a step, only feedthrough outputs need an update at t + h;
        # a dynamic instance's own inputs are set when its next step starts.
        self._final_order = [
            p for p in self._order
            if p in self._first or any(
                self.wiring.feedthrough_outputs.get((p.inst.name, n), self._feeds(p.inst, n))
                for n in p.out_names)
        ]

    # -- initialization --------------------------------------------------

    def initialize(self, parameters: dict[str, dict[str, object]]) -> None:
        """Set up every instance, resolve the initial outputs, leave init mode."""
        for name, inst in self.instances.items():
            inst.setup(self.start_time, parameters.get(name, {}))
        # Outputs in initialization mode follow from parameters; two sweeps
        # settle feedthrough chains of any depth found in these scenes.
        for _ in range(2):
            self._propagate(self._order)
        for inst in self.instances.values():
            inst.exit_init()
        self._propagate(self._order)
        self.t = self.start_time
        self._reset_soft_state()
        self._z_end = self._indicators()
        if self._z_sources_any:
            # The sources' time scale caps the very first step too (a first
            # step over several crossings would hide them). When the start
            # says nothing (at rest at zero), the first step is short instead.
            self._remember_indicator_sources()
            if self._event_step_cap == math.inf:
                self._z_src_prev = None

    def reinitialize(self, parameters: dict[str, dict[str, object]]) -> None:
        """fmi2Reset every instance and initialize again (shooting uses this)."""
        for inst in self.instances.values():
            inst.reset()
        self.initialize(parameters)

    def discontinuity(self) -> None:
        """Tell the master that something changed outside the wiring at this
        communication point (a tunable parameter, an unconnected input): the
        input polynomials restart from zero-order hold, finite differences
        forget the past, and the next step takes a fresh checkpoint so that a
        replay never reaches back across the change."""
        self._after_event = True
        self._time_to_zero = 0.0
        for hist in self._history.values():
            hist.times.clear()
            hist.values.clear()
        self._record_history()

    def _reset_soft_state(self) -> None:
        for h in self._history.values():
            h.times.clear()
            h.values.clear()
        self._checkpoint = None
        self._since_checkpoint = []
        self._after_event = True
        self._z_src_prev = None
        self._src_amp = [(0.0, 0.0)] * len(self._z_sources)
        self._z_seen = [None] * len(self._z_sources)
        self._event_step_cap = math.inf
        self._du_end_cache = {}  # indicator -> d(source)/dt at the step end
        self._stale_sources = False
        self._record_history()

    # -- the communication step ----------------------------------------

    def _propagate(self, ports: list[_Port]) -> None:
        """Set inputs from their sources and read outputs, in order."""
        t = self.t
        for p in ports:
            if p.n_in:
                inp = p.inp
                for k, src, j in p.sources:
                    inp[k] = src.out[j]
                st = p.inst.c_setReal(p.comp, p.in_vr, p.n_in, inp)
                if st > WARNING:
                    raise p.inst.fail("fmi2SetReal of inputs", st, t)
                p.sent_valid = False
            if p.n_out:
                st = p.inst.c_getReal(p.comp, p.out_vr, p.n_out, p.out)
                if st > WARNING:
                    raise p.inst.fail("fmi2GetReal", st, t)
            p.out_time = t

    def _read(self, p: _Port, t: float) -> None:
        if p.n_out:
            st = p.inst.c_getReal(p.comp, p.out_vr, p.n_out, p.out)
            if st > WARNING:
                raise p.inst.fail("fmi2GetReal", st, t)
        p.out_time = t

    def _set_inputs(self, p: _Port, t: float, h: float, coupling_end: list[float] | None = None) -> None:
        """Inputs of a dynamic instance for the step from t.

        Sources that already stepped (Gauss-Seidel) hold values at t + h;
        with extrapolation the polynomial through them is re-anchored at t,
        which makes it an interpolation over the step.
        """
        inp = p.inp
        if coupling_end is not None:
            starts, coupling_end = coupling_end
            for k in range(p.n_in):
                inp[k] = starts[k]
        else:
            for k, src, j in p.sources:
                inp[k] = src.out[j]
        polynomial = self._extrapolating and not self._after_event and coupling_end is None
        if polynomial:
            self._extrapolate(p, t)
        elif coupling_end is None and p.sent_valid and p.sent == inp[:p.n_in]:
            return  # held value unchanged: the FMU already has it
        st = p.setReal(p.comp, p.in_vr, p.n_in, inp)
        if st > WARNING:
            raise p.inst.fail("fmi2SetReal of inputs", st, t)
        p.sent = inp[:p.n_in]
        p.sent_valid = not polynomial and coupling_end is None
        if coupling_end is not None:
            # Strong coupling: interpolate linearly towards the last iterate.
            for k in range(p.n_in):
                p.der[k] = (coupling_end[k] - inp[k]) / h
                p.der[p.n_in + k] = 0.0
            self._set_derivatives(p, t, 1)
        elif polynomial:
            self._set_derivatives(p, t, self.settings.extrapolation)

    def _set_derivatives(self, p: _Port, t: float, order: int) -> None:
        n = p.n_in * (2 if order >= 2 else 1)
        st = p.inst.c_setInputDerivatives(p.comp, p.der_vr, n, p.der_order, p.der)
        if st > WARNING:
            raise p.inst.fail("fmi2SetRealInputDerivatives", st, t)

    def _derivative_sources(self) -> dict:
        """For each dynamic input: a source offering output derivatives, if any."""
        found = {}
        for p in self._dynamic:
            for k, src, j in p.sources:
                inst = src.inst
                name = src.out_names[j]
                var = inst.variables[name]
                has_feed = var.dependencies is None or len(var.dependencies) > 0
                if not has_feed and inst.max_output_derivative_order >= 1:
                    got = inst.output_derivatives([name], 1)
                    if got is not None:
                        m = 2 if inst.max_output_derivative_order >= 2 else 1
                        found[(p.inst.name, k)] = (
                            inst, (c_uint * 2)(var.vr, var.vr), (c_int * 2)(1, 2), (c_double * 2)(), m)
        return found

    def _extrapolate(self, p: _Port, t: float) -> None:
        """Fill p.inp (values at t) and p.der (derivatives at t) from the sources."""
        order = self.settings.extrapolation
        hist = self._history[p.inst.name]
        n = p.n_in
        for k, (_, src, j) in enumerate(p.sources):
            ta, ua = src.out_time, src.out[j]
            d1 = d2 = 0.0
            dsrc = self._deriv_sources.get((p.inst.name, k))
            if dsrc is not None:
                inst, vrs, orders, out, m = dsrc
                m = min(m, order)
                if inst.c_getOutputDerivatives(inst.component, vrs, m, orders, out) <= WARNING:
                    d1 = out[0]
                    d2 = out[1] if m == 2 else 0.0
            else:
                # Divided differences through the history and the current value.
                pts = [(tt, vv[k]) for tt, vv in zip(hist.times, hist.values) if tt < ta - 1e-15]
                pts = pts[-order:] + [(ta, ua)]
                if len(pts) >= 2:
                    (t1, u1), (t2, u2) = pts[-2], pts[-1]
                    d1 = (u2 - u1) / (t2 - t1)
                    if order >= 2 and len(pts) >= 3:
                        t0, u0 = pts[-3]
                        d0 = (u1 - u0) / (t1 - t0)
                        d2 = 2.0 * (d1 - d0) / (t2 - t0)
                        d1 += 0.5 * d2 * (t2 - t1)
            dt = t - ta
            p.inp[k] = ua + dt * (d1 + 0.5 * dt * d2)
            p.der[k] = d1 + d2 * dt
            p.der[n + k] = d2

    def _record_history(self) -> None:
        if not self.settings.extrapolation:
            return
        if self._after_event_step or self._after_event:
            # Values before a discontinuity say nothing about the signal after it.
            for hist in self._history.values():
                hist.times.clear()
                hist.values.clear()
        for p in self._dynamic:
            if not p.n_in:
                continue
            hist = self._history[p.inst.name]
            hist.times.append(self.t)
            hist.values.append([src.out[j] for _, src, j in p.sources])
            if len(hist.times) > 3:
                del hist.times[0], hist.values[0]

    def _indicators(self) -> list[float]:
        if len(self._z_spans) == 1:
            a, b, out = self._z_spans[0]
            return out[a:b]
        z = []
        for a, b, out in self._z_spans:
            z += out[a:b]
        return z

    def _advance(self, t: float, h: float, coupling: dict | None = None) -> None:
        """One communication step from t to t + h of every instance."""
        t_new = t + h
        for p in self._first:
            st = p.doStep(p.comp, t, h, 0)
            if st > WARNING:
                raise self._step_failure(p, st, t, h)
            if p.z_pos and self._after_event:
                # A commit may have switched the mode: read z at t+.
                p.getReal(p.comp, p.out_vr, p.n_out, p.out)
        if self._locating:
            # Without a commit of a new mode, z at t+ is z at t.
            self._z_start = self._indicators() if self._after_event else self._z_end
        jacobi = self._jacobi
        dynamic = self._dynamic
        if jacobi:
            for p in dynamic:
                if p.n_in:
                    self._set_inputs(p, t, h, coupling.get(p.inst.name) if coupling else None)
        last = dynamic[-1] if dynamic else None
        for p in dynamic:
            if not jacobi and p.n_in:
                self._set_inputs(p, t, h, coupling.get(p.inst.name) if coupling else None)
            st = p.doStep(p.comp, t, h, 0)
            if st > WARNING:
                raise self._step_failure(p, st, t, h)
            if p.n_out:
                st = p.getReal(p.comp, p.out_vr, p.n_out, p.out)
                if st > WARNING:
                    raise p.inst.fail("fmi2GetReal", st, t_new)
            p.out_time = t_new
            if not jacobi and p is not last:
                # Newest values flow on to the instances stepped later.
                saved_t, self.t = self.t, t_new
                self._propagate(self._first_in_order)
                self.t = saved_t
        self.t = t_new
        for p in self._final_order:
            if p.n_in:
                inp = p.inp
                for k, src, j in p.sources:
                    inp[k] = src.out[j]
                st = p.setReal(p.comp, p.in_vr, p.n_in, inp)
                if st > WARNING:
                    raise p.inst.fail("fmi2SetReal of inputs", st, t_new)
                p.sent_valid = False
            if p.n_out:
                st = p.getReal(p.comp, p.out_vr, p.n_out, p.out)
                if st > WARNING:
                    raise p.inst.fail("fmi2GetReal", st, t_new)
            p.out_time = t_new
        if self._locating:
            self._z_end = self._indicators()

    @staticmethod
    def _step_failure(p: _Port, st: int, t: float, h: float) -> SimulationError:
        if st == DISCARD:
            return SimulationError(
                f"{p.inst.name}: fmi2DoStep from t = {t!r} s with h = {h!r} s was discarded: "
                f"{p.inst.last_message()}", time=t, instance=p.inst.name)
        return p.inst.fail(f"fmi2DoStep({t!r}, {h!r})", st, t)

    def _save_all(self) -> None:
        for p in self._all:
            p.inst.save_state()
        self.stats.states_saved += 1

    def _restore_all(self) -> None:
        for p in self._all:
            p.inst.restore_state()
            p.sent_valid = False
        if self._du_end_cache:
            self._du_end_cache = {}
        self.stats.rollbacks += 1

    def _soft_state(self) -> tuple:
        return (
            self._z_end,
            self.t,
            {n: (list(h.times), [list(v) for v in h.values]) for n, h in self._history.items()},
            self._after_event,
            self._time_to_zero,
        )

    def _restore_soft_state(self, snap: tuple) -> None:
        self._z_end, self.t, hist, self._after_event, self._time_to_zero = snap
        for n, (times, values) in hist.items():
            self._history[n].times[:] = times
            self._history[n].values[:] = [list(v) for v in values]
        # The FMU states hold their inputs; only the cached outputs are stale.
        for p in self._all:
            self._read(p, self.t)

    @staticmethod
    def _crossed(z0: float, z1: float) -> bool:
        return (z0 > 0.0 and z1 <= 0.0) or (z0 < 0.0 and z1 >= 0.0)

    @staticmethod
    def _scan(z0: list[float], z1: list[float], h: float) -> float:
        """-1 when an indicator changed sign over the step of h s; else the
        time, s, until the nearest one would reach zero at its rate over the
        step, in either direction (a turn-around is also a risk)."""
        steps = math.inf
        for a, b in zip(z0, z1):
            if (a > 0.0 and b <= 0.0) or (a < 0.0 and b >= 0.0):
                return -1.0
            dist = abs(b)
            if dist <= 1e-15:
                return 0.0
            change = abs(b - a)
            if dist < steps * change:
                steps = dist / change
        return steps * h

    def step(self, h: float) -> float:
        """Advance by at most h (less when an event is located). Returns the step taken."""
        s = self.settings
        t = self.t
        if self._z_sources_any:
            if self._z_src_prev is None:
                h *= 1.0 / 64  # no time scale known yet: a short first step
            elif h > self._event_step_cap:
                h = self._event_step_cap
        self._after_event_step = False
        needs_rollback = self._needs_rollback
        locating = self._locating
        # Could an indicator reach zero in this step? Conservative: at 4x
        # the last step's rate of change.
        near = locating and (self._after_event or self._time_to_zero <= 4.0 * h)
        # A checkpoint also bounds how far back a replay must go.
        possible = near or (locating and len(self._since_checkpoint) >= self.MAX_REPLAY_STEPS)
        if near and self._stale_sources:
            # The hidden-crossing check needs the sources at the step start.
            self._remember_indicator_sources()
            self._stale_sources = False
        if possible or needs_rollback:
            self._save_all()
            self._checkpoint = self._soft_state()
            self._since_checkpoint = []
        if not needs_rollback:
            self._advance(t, h)
        elif s.richardson:
            h = self._richardson_step(t, h)
        else:
            self._coupled_step(t, h)
        taken = h
        if locating:
            z0, z1 = self._z_start, self._z_end
            time_to_zero = self._scan(z0, z1, h)
            hit = time_to_zero < 0.0
            if not hit and self._z_sources_any and near:
                hidden = self._hidden_crossing(h, z0, z1)
                if hidden is not None:
                    # Two crossings inside one step cancel at its ends; try
                    # the step up to the interpolant's extremum.
                    if not (possible or needs_rollback):
                        self._replay_to(t)
                    self._restore_all()
                    self._restore_soft_state(self._checkpoint)
                    self._advance(t, hidden)
                    self.stats.event_iterations += 1
                    z0, z1 = self._z_start, self._z_end
                    time_to_zero = self._scan(z0, z1, hidden)
                    hit = time_to_zero < 0.0
                    if hit:
                        h = hidden
                        possible = near = True
                    else:  # the interpolant was wrong: redo the whole step
                        self._restore_all()
                        self._restore_soft_state(self._checkpoint)
                        self._advance(t, h)
                        z0, z1 = self._z_start, self._z_end
                        time_to_zero = self._scan(z0, z1, h)
            if hit:
                crossed = [(a > 0.0 and b <= 0.0) or (a < 0.0 and b >= 0.0) for a, b in zip(z0, z1)]
                z0, z1 = list(z0), list(z1)
                if not (possible or needs_rollback):
                    self._replay_to(t)
                    self._advance(t, h)  # back at t + h, now with a checkpoint at t
                taken = self._locate(t, h, crossed, z0, z1)
                self._time_to_zero = 0.0
                self._since_checkpoint.append(self.t - self._located_from)
            else:
                self._time_to_zero = time_to_zero
                self._since_checkpoint.append(taken)
        if self._z_sources_any:
            # Sources are sampled where a crossing is near, and now and then
            # to keep the time-scale estimate behind the step cap fresh.
            self._sample_countdown -= 1
            if near or self._sample_countdown <= 0 or self._z_src_prev is None:
                self._remember_indicator_sources()
                self._sample_countdown = 16
                self._stale_sources = False
            else:
                self._stale_sources = True
        self._after_event = self._after_event_step
        self.stats.steps += 1
        if not sum(map(abs, self._outputs)) < self.settings.divergence_limit:  # NaN fails too
            self._check_finite()
        if self._extrapolating:
            self._record_history()
        if self.on_step is not None:
            self.on_step(self)
        return taken

    MAX_REPLAY_STEPS = 64  # a forced checkpoint bounds replay work and memory

    _after_event_step = False

    def _replay_to(self, t: float) -> None:
        """An event in a step predicted free of events: go back and redo."""
        self.stats.replays += 1
        if self._checkpoint is None:
            raise SimulationError(
                f"an event indicator changed sign at t = {t!r} s in a step without a checkpoint",
                time=t)
        self._restore_all()
        steps = list(self._since_checkpoint)
        self._restore_soft_state(self._checkpoint)
        for h in steps:
            self._advance(self.t, h)
            self._record_history()
        if abs(self.t - t) > 1e-9 * max(1.0, abs(t)):
            raise SimulationError(f"replay ended at t = {self.t!r} s instead of {t!r} s", time=t)
        self.t = t
        self._save_all()
        self._checkpoint = self._soft_state()
        self._since_checkpoint = []

    def _locate(self, t: float, h: float, crossed: list[bool], z0: list[float], z1: list[float]) -> float:
        """Shorten the step to land just past the earliest crossing.

        The first trial comes from a cubic Hermite interpolant of the lead
        indicator, its slopes taken from the derivatives of the output it
        depends on (e.g. the pendulum's dphi/dt = w); then Illinois
        iteration on the bracket until the crossing is bracketed to the time
        tolerance or the indicator is within its tolerance.
        """
        s = self.settings
        # The indicator whose linear interpolant crosses first leads.
        lead = min((k for k, c in enumerate(crossed) if c), key=lambda k: z0[k] / (z0[k] - z1[k]))
        slope_end = self._indicator_slope_source(lead)
        self._restore_all()
        self._restore_soft_state(self._checkpoint)
        first = None
        newton = None  # (ratio dz/du, instance, vr) for Newton steps after each trial
        if slope_end is not None:
            (u1, du1), src, pos, inst, vr = slope_end
            u0, du0 = src.out[pos], self._output_rate(inst, vr)
            if du0 is not None and u1 != u0:
                ratio = (z1[lead] - z0[lead]) / (u1 - u0)
                first = hermite_root(h, z0[lead], ratio * du0, z1[lead], ratio * du1)
                newton = (ratio, inst, vr, lead)
        search = Illinois(0.0, z0[lead], h, z1[lead])
        hi, z_hi = h, list(z1)
        z_lo = list(z0)
        base = 0.0  # offset from t of the checkpoint the trials start from
        last = None  # the FMUs stand at the checkpoint after the restore above
        # Far from t = 0 a double cannot resolve the tolerance: use a few ulps.
        time_tol = max(s.event_time_tolerance, 4 * math.ulp(abs(t) + h))
        while True:
            if hi - search.lo <= time_tol or abs(z_hi[lead]) <= s.event_indicator_tolerance:
                break
            trial, first = (first, None) if first is not None else (search.next(), None)
            if not (search.lo < trial < hi):
                trial = 0.5 * (search.lo + hi)
            # A trial must move the FMUs' clock: at least a few ulps past lo.
            min_move = 8 * math.ulp(abs(t) + abs(hi) + 1.0)
            if (t + trial) - (t + search.lo) < min_move:
                trial = search.lo + min(0.5 * (hi - search.lo), max(min_move, 0.25 * s.event_time_tolerance))
            if last is not None:
                self._restore_all()
                self._restore_soft_state(self._checkpoint)
            self._advance(self.t, (t + trial) - self.t)
            self.stats.event_iterations += 1
            last = trial
            z = self._z_end
            if newton is not None and newton[3] == lead:
                # Newton from this trial, with dz/dt = (dz/du) du/dt, aimed a
                # hair past the root so that the landing point has crossed.
                rate = self._output_rate(newton[1], newton[2])
                if rate:
                    slope = newton[0] * rate
                    delta = -z[lead] / slope
                    past = min(0.25 * s.event_time_tolerance, 0.25 * s.event_indicator_tolerance / abs(slope))
                    first = trial + delta + math.copysign(past, delta)
            now = [self._crossed(a, b) for a, b in zip(self._z_start, z)]
            if any(now):
                earlier = [k for k, c in enumerate(now) if c]
                if lead not in earlier:
                    # Another indicator crosses first: restart on it.
                    lead = min(earlier, key=lambda k: z_lo[k] / (z_lo[k] - z[k]))
                    search = Illinois(search.lo, z_lo[lead], trial, z[lead])
                    first = None
                else:
                    search.update(trial, z[lead], crossed=True)
                hi, z_hi = trial, list(z)
            else:
                search.update(trial, z[lead], crossed=False)
                # Later trials start here: no need to integrate [t, t + trial] again.
                z_lo = list(z)
                self._save_all()
                self._checkpoint = self._soft_state()
                base, last = trial, None
            if search.iterations > 200:
                raise SimulationError(
                    f"event location did not converge in (t, t+h) = ({t!r}, {t + h!r}) s", time=t)
        if last != hi:
            if last is not None:
                self._restore_all()
                self._restore_soft_state(self._checkpoint)
            self._advance(self.t, (t + hi) - self.t)
        self._since_checkpoint = [] if base > 0.0 else self._since_checkpoint
        self._located_from = t + base
        self.stats.events += 1
        self._after_event_step = True
        return hi

    def _remember_indicator_sources(self) -> None:
        """Values and rates of the indicators' source outputs at this point.

        They also bound the step: the hidden-crossing check interpolates over
        a step, which is reliable up to about a quarter of the source's
        oscillation period, estimated as 2 pi max|u| / max|du/dt| over the
        recent past (slowly forgotten).
        """
        mem = []
        cap = math.inf
        for k, info in enumerate(self._z_sources):
            if info is None:
                mem.append(None)
                continue
            src, pos, inst, vr = info
            u = src.out[pos]
            z_now = self._z_end[k] if k < len(self._z_end) else None
            constant = z_now is not None and z_now == self._z_seen[k]
            self._z_seen[k] = z_now
            if constant:
                # An indicator that did not move says nothing about its
                # source's time scale, and has no hidden crossing to look for.
                mem.append((u, None))
                continue
            du = self._du_end_cache.get(k)
            if du is None:
                du = self._output_rate(inst, vr)
            mem.append((u, du))
            if du is not None:
                amp_u, amp_du = self._src_amp[k]
                amp_u = max(abs(u), 0.999 * amp_u)
                amp_du = max(abs(du), 0.999 * amp_du)
                self._src_amp[k] = (amp_u, amp_du)
                omega = amp_du / amp_u if amp_u > 0.0 else 0.0
                # At a turning point |du| says nothing yet; |d2u/dt2| / |u| does.
                if inst.max_output_derivative_order >= 2 and u != 0.0:
                    acc = self._output_rate(inst, vr, order=2)
                    if acc is not None:
                        omega = max(omega, math.sqrt(abs(acc / u)))
                if omega > 0.0:
                    cap = min(cap, 0.2 * 2 * math.pi / omega)
        self._z_src_prev = mem
        self._event_step_cap = cap
        self._du_end_cache = {}

    def _hidden_crossing(self, h: float, z0: list[float], z1: list[float]) -> float | None:
        """Offset of an indicator's extremum inside the step, when its Hermite
        interpolant (slopes from the source outputs' derivatives) changes
        sign there although z has the same sign at both ends; else None."""
        prev = self._z_src_prev
        if prev is None:
            return None
        best = None
        for k, info in enumerate(self._z_sources):
            if info is None or prev[k] is None or prev[k][1] is None:
                continue
            src, pos, inst, vr = info
            u0, du0 = prev[k]
            u1 = src.out[pos]
            if u1 == u0 or z0[k] == 0.0:
                continue
            ratio = (z1[k] - z0[k]) / (u1 - u0)
            dz0 = ratio * du0
            if z0[k] * dz0 >= 0.0:
                continue  # moving away from zero at the start: no early crossing
            du1 = self._output_rate(inst, vr)
            if du1 is None:
                continue
            self._du_end_cache[k] = du1
            dz1 = ratio * du1
            if z1[k] * dz1 <= 0.0:
                continue  # still approaching at the end: no turn inside the step
            x = hermite_extremum(h, z0[k], dz0, z1[k], dz1)
            if x is not None and (best is None or x < best):
                best = x
        return best

    def _indicator_slope_source(self, k: int):
        """For indicator k: ((u, du/dt) now, source port, position, instance, vr) of
        the single connected output it depends on, when that output offers a
        time derivative; else None."""
        info = self._z_sources[k]
        if info is None:
            return None
        src, pos, inst, vr = info
        rate = self._output_rate(inst, vr)
        if rate is None:
            return None
        return (src.out[pos], rate), src, pos, inst, vr

    def _output_rate(self, inst: Instance, vr, order: int = 1) -> float | None:
        out = self._rate_buffer  # per master: masters may run in threads
        orders = _ORDER_ONE if order == 1 else _ORDER_TWO
        if inst.c_getOutputDerivatives(inst.component, vr, 1, orders, out) > WARNING:
            return None
        return out[0]

    def _indicator_sources(self) -> list:
        found = []
        for p in self._indicator_ports:
            for k in p.z_pos:
                name = p.out_names[k]
                deps = p.inst.variables[name].dependencies or []
                info = None
                if len(deps) == 1 and deps[0] in p.in_names:
                    k_in = p.in_names.index(deps[0])
                    for kk, src, j in p.sources:
                        if kk == k_in:
                            var = src.inst.variables[src.out_names[j]]
                            if src.inst.max_output_derivative_order >= 1 and not self._feeds(src.inst, var.name):
                                info = (src, j, src.inst, (c_uint * 1)(var.vr))
                found.append(info)
        return found

    def _coupled_step(self, t: float, h: float) -> None:
        """Fixed-point iteration of the step on the dynamic-to-dynamic inputs."""
        s = self.settings
        starts = {p.inst.name: [src.out[j] for _, src, j in p.sources] for p in self._dynamic if p.n_in}
        self._advance(t, h)
        for _ in range(s.iterations):
            ends = {p.inst.name: (starts[p.inst.name], [src.out[j] for _, src, j in p.sources])
                    for p in self._dynamic if p.n_in}
            self._restore_all()
            self._restore_soft_state(self._checkpoint)
            self._advance(t, h, coupling=ends)
            self.stats.coupling_iterations += 1
            change = max(
                (abs(src.out[j] - ends[p.inst.name][1][k]) for p in self._dynamic if p.n_in
                 for k, (_, src, j) in enumerate(p.sources)),
                default=0.0,
            )
            if change <= s.iteration_tolerance:
                break

    def _richardson_step(self, t: float, h: float) -> float:
        """Step doubling: compare one step of h with two of h/2; adapt h."""
        s = self.settings
        p_order = s.extrapolation + 1
        while True:
            self._advance(t, h)
            full = self._dynamic_outputs()
            self._restore_all()
            self._restore_soft_state(self._checkpoint)
            self._advance(t, 0.5 * h)
            z_start = self._z_start  # the indicators must span the whole step
            self._record_history()
            self._advance(t + 0.5 * h, 0.5 * h)
            self._z_start = z_start
            half = self._dynamic_outputs()
            err = max(
                (abs(a - b) / (s.richardson_tolerance * (1.0 + abs(b))) for a, b in zip(full, half)),
                default=0.0,
            ) / (2 ** p_order - 1)
            if err <= 1.0 or h <= s.min_step:
                factor = 0.9 * err ** (-1.0 / (p_order + 1)) if err > 0 else 2.0
                self._richardson_next = min(max(factor, 0.2), 2.0) * h
                if s.max_step:
                    self._richardson_next = min(self._richardson_next, s.max_step)
                return h
            self.stats.rejected += 1
            h = max(s.min_step, h * max(0.2, 0.9 * err ** (-1.0 / (p_order + 1))))
            self._restore_all()
            self._restore_soft_state(self._checkpoint)

    _richardson_next: float | None = None

    def _dynamic_outputs(self) -> list[float]:
        return [p.out[k] for p in self._dynamic for k in range(p.n_out)]

    @staticmethod
    def _feeds(inst: Instance, name: str) -> bool:
        v = inst.variables[name]
        return v.causality == "output" and (v.dependencies is None or len(v.dependencies) > 0)

    def _check_finite(self) -> None:
        """Name the output that failed step()'s one-pass test over all outputs
        (a sum of large but legal outputs can fail it too: then nothing)."""
        limit = self.settings.divergence_limit
        for p in self._all:
            if sum(map(abs, p.out)) < limit:
                continue
            out = p.out
            for k in range(p.n_out):
                x = out[k]
                if not (-limit < x < limit):
                    what = "is not finite" if not math.isfinite(x) else f"exceeds the divergence limit {limit:g}"
                    raise SimulationError(
                        f"{p.inst.name}.{p.out_names[k]} = {x!r} {what} at t = {self.t!r} s",
                        time=self.t, instance=p.inst.name, variable=p.out_names[k])

    # -- running ----------------------------------------------------------

    def run_until(self, t_stop: float, on_point=None) -> None:
        """Step to t_stop on the grid start + k*step, plus located events.

        Grid points are computed as start + k*step, never by summing steps,
        so that time does not drift.
        """
        s = self.settings
        h_nom, t0 = s.step, self.start_time
        eps = 1e-12 * max(1.0, abs(t_stop))
        k = math.floor((self.t - t0) / h_nom + 1e-9) + 1
        step = self.step
        while self.t < t_stop - eps:
            grid = t0 + k * h_nom
            if grid > t_stop:
                grid = t_stop
            if s.richardson and self._richardson_next is not None:
                grid = min(self.t + max(self._richardson_next, s.min_step), t_stop)
            h = grid - self.t
            if h <= eps:
                k += 1
                continue
            step(h)
            if on_point is not None:
                on_point(self)
            if self.t >= grid - eps:
                k += 1

    def terminate(self) -> None:
        for inst in self.instances.values():
            try:
                inst.free()
            except Exception:
                pass
