"""Multi-rate stepping: each component at its own communication step, a
whole multiple k (its decimation factor) of the base step h (master.step).

The rule is libcosim's fixed-step algorithm's (fixed_step_algorithm.cpp),
so that the same system gives the same numbers:

- a component of factor k takes one step of k * h every k base steps, from
  a point of its own grid (start + m * k * h) to the next;
- a value passes along a link only at the points both of its ends share
  (every lcm(k_source, k_target) base steps); in between, the target's
  input holds what passed last. A slow component's inputs are thus the
  values at its own step's start (a zero-order hold over its step), and a
  fast one sees a slow one's outputs as they were at their last shared
  point.

clockwork takes a slow component's step in the base step that ends where
its own step ends (libcosim takes it in the first, and passes its outputs
on at the end): the numbers passed are the same, and between its points a
slow component's recorded outputs are those of its last point, never of a
later time. Its outputs are read after its own steps only (never set and
read at t + h as a feedthrough output at the base rate is).

Event location (indicators at the base rate) and extrapolation run with
the master's accurate step (``TimedMultiRate``). What needs every
component at one time (strong coupling, step doubling), indicators that
change at a slow component's points only and algebraic loops with a slow
member are refused in one line (``problem``, ``loop_problem``) rather
than done differently. A scene whose components all step at master.step
never comes here: the master takes its single-rate path, with the same
bits as before.

The compiled core's twin of ``MultiRate`` is src_c/master/cw_rates.c (the
same bits, by tests/test_multirate.py); what it does not do across rates
(``TimedMultiRate``'s part among them) is decided in
compiled.unsupported_rates.
"""

from __future__ import annotations

import math

from ..errors import SceneError, SimulationError, UsageError
from ..fmi.calls import WARNING

# How far a component's step may be from a whole multiple of the base step,
# relative to the step (decimal steps such as 0.03 / 0.01 are not exact in binary).
RELATIVE_ROUNDING = 1e-9


def decimation(step: float, base: float) -> int | None:
    """The whole number k with step = k * base within rounding, or None."""
    if not (step > 0 and base > 0 and math.isfinite(step) and math.isfinite(base)):
        return None
    k = round(step / base)
    if k < 1 or abs(step - k * base) > RELATIVE_ROUNDING * step:
        return None
    return k


def is_multirate(rates: dict[str, int] | None) -> bool:
    return bool(rates) and any(k != 1 for k in rates.values())


def slow_ones(rates: dict[str, int]) -> str:
    """The components that do not step at the base step, said as "v every 3"."""
    return ", ".join(f"{n} every {k}" for n, k in rates.items() if k != 1)


# The base steps a master across rates refuses (both engines: MultiRate.step,
# src_c/master/cw_rates.c's rates_step), each from (t, the step or the
# event's time, the base step), s; the core names one by its position here.
def off_base_step(t: float, h: float, base: float) -> UsageError:
    return UsageError(f"a step of {h!r} s from t = {t!r} s: components step at different rates, each a "
                      f"multiple of master.step, and the master takes whole base steps ({base!r} s) only")


def time_event_inside(t: float, te: float, base: float) -> SimulationError:
    return SimulationError(f"a time event an FMU announced at t = {te!r} s falls inside the base step from "
                           f"t = {t!r} s: components step at different rates and the master does not shorten a "
                           "step (master.step on the events' grid)")


def sample_event_inside(t: float, te: float, base: float) -> SimulationError:
    return SimulationError(f"the input samples' event at t = {te!r} s falls inside the base step from t = {t!r} s: "
                           "components step at different rates and the master does not shorten a step (events on "
                           "the grid of master.step)")


REFUSALS = (off_base_step, time_event_inside, sample_event_inside)


def problem(settings, rates: dict[str, int], indicators: dict[str, object],
            links: list[tuple[str, str]] = ()) -> tuple[str, str] | None:
    """What of these master settings cannot run with these decimation
    factors, as (the first slow instance, the line that says which setting
    and what was expected), or None. `indicators`: per instance, its event
    indicators (empty where it has none); `links`: (source instance,
    target instance) of each connection."""
    if not is_multirate(rates):
        return None
    first = next(n for n, k in rates.items() if k != 1)
    why = f"components step at different rates ({slow_ones(rates)} base steps)"
    alike = "or every component at master.step"
    if settings.iterations > 0:
        return first, (f"master.iterations = {settings.iterations}: expected 0: strong coupling repeats one step of "
                       f"every component, and {why}; {alike}")
    if settings.richardson:
        return first, (f"master.richardson = true: expected false: step doubling halves one step of every "
                       f"component, and {why}; {alike}")
    if settings.event_location:
        located = [n for n, z in indicators.items() if z and rates.get(n, 1) != 1]
        if located:
            return located[0], (f"master.event_location = true: expected false or {', '.join(located)} at "
                                 f"master.step: the event indicators of a slow component are known at its own "
                                 f"points only, and {why}")
        fed = [(a, b) for a, b in links if indicators.get(b) and rates.get(a, 1) != 1]
        if fed:
            a, b = fed[0]
            return a, (f"master.event_location = true: expected false or {a} at master.step: {b}'s event "
                       f"indicators read {a}'s outputs, which change at {a}'s own points only, and {why}")
    return None


def timed(settings, rates: dict[str, int], indicators: dict[str, object]) -> str | None:
    """What of these settings needs the master's accurate step across rates
    (TimedMultiRate: event location, extrapolation), said in a few words, or
    None where the plain multi-rate stepping (MultiRate) runs them."""
    if not is_multirate(rates):
        return None
    if settings.extrapolation:
        return f"master.extrapolation = {settings.extrapolation} across rates"
    located = [n for n, z in indicators.items() if z]
    if settings.event_location and located:
        return f"event location across rates ({', '.join(located)} declare{'s' * (len(located) == 1)} indicators)"
    return None


def loop_problem(rates: dict[str, int], loops: list[tuple[str, list[str]]]) -> str | None:
    """An algebraic loop ((its name, its members' names)) with a member that
    does not step at the base step, said in one line, or None."""
    if not is_multirate(rates):
        return None
    for name, members in loops:
        slow = [n for n in members if rates.get(n, 1) != 1]
        if slow:
            return (f"algebraic loop {name}: {', '.join(slow)} steps every "
                    f"{rates[slow[0]]} base steps: a loop is solved at every base step; expected every member "
                    "at master.step")
    return None


def stop_problem(rates: dict[str, int], base: float, start: float, stop: float) -> str | None:
    """The run must end on the base grid: a last, shorter base step has no
    meaning for a component in the middle of its own."""
    if not is_multirate(rates):
        return None
    n = (stop - start) / base
    if abs(n - round(n)) > 1e-9 * max(1.0, n):
        return (f"expected a whole number of base steps ({base!r} s) after the start, got {stop!r} s: "
                "components step at different rates")
    return None


class _Held:
    """A source as a target of another rate sees it: the outputs as they
    were at the last point both share (``out`` and ``dout`` as a Port's,
    passed at ``out_time``, s), with their polynomial there where inputs
    are extrapolated (``d1``, ``d2``: first and second time derivatives;
    ``past``: per output, the (time, value) pairs passed before, for
    divided differences)."""

    __slots__ = ("inst", "out_names", "dout_names", "out", "dout", "out_time", "d1", "d2", "past")

    def __init__(self, src):
        self.inst, self.out_names, self.dout_names = src.inst, src.out_names, src.dout_names
        self.out = list(src.out)
        self.dout = list(src.dout)
        self.out_time = src.out_time
        self.d1 = [0.0] * len(self.out)
        self.d2 = [0.0] * len(self.out)
        self.past: list[list[tuple[float, float]]] = [[] for _ in self.out]


class MultiRate:
    """The stepping of a master (engine/master.Master) whose components step
    at different rates: ``step`` replaces the master's."""

    MAX_TABLE = 4096  # base steps of a period whose due lists are made once

    def __init__(self, master, rates: dict[str, int]):
        self.master = master
        ports = master.ports
        self.k = {p.inst.name: rates.get(p.inst.name, 1) for p in ports.all}
        for p in ports.first:
            if self.k[p.inst.name] != 1:  # wiring demotes slow instances to dynamic ones (Master.__init__)
                raise AssertionError(f"{p.inst.name}: a slow instance stepped first")
        # The links across rates: (target port, input position, held source, source port, position, every)
        self.real: list = []
        self.discrete: list = []
        self.held: dict[tuple[int, int], _Held] = {}  # (id target, id source) -> its _Held
        self._attached = False
        self.count = 0  # base steps taken since the start
        self.period = math.lcm(*self.k.values())
        # Per base step in the period: the dynamic ports whose own step ends there, in stepping order
        # (found at each step where the period is long: factors may be large and coprime).
        self._rated = [(p, self.k[p.inst.name]) for p in ports.dynamic]
        self.due = ([self._due(n) for n in range(self.period)] if self.period <= self.MAX_TABLE else None)
        self.fast_dynamic = [p for p in ports.dynamic if self.k[p.inst.name] == 1]
        self.slow = [p for p in ports.dynamic if self.k[p.inst.name] != 1]
        self.starts: dict[int, float] = {}  # id(slow port) -> where its step now under way started, s
        self.updates_after = dict(zip(map(id, ports.dynamic), master._updates_after))

    def _due(self, n: int) -> list:
        """The dynamic ports whose own step ends with base step n (counted from 0)."""
        return [p for p, k in self._rated if (n + 1) % k == 0]

    def _own_step(self, p, t_new: float) -> tuple[float, float]:
        """(start, step) of the own step of `p` that ends at t_new, s: from
        the communication point where it started, so that both ends are the
        master's own grid points (start + m * master.step)."""
        start = self.starts[id(p)]
        return start, t_new - start

    # -- the links across rates ------------------------------------------

    def attach(self) -> None:
        """Route every link across rates through a held copy of its source,
        filled with the values now (after Initialization Mode, where every
        value passes, as libcosim's does)."""
        if self._attached:
            self._fill_all()
            return
        k = self.k
        for p in self.master.ports.all:
            kt = k[p.inst.name]
            p.sources, p.adds = self._routed(p, p.sources), self._routed(p, p.adds)  # adds: a sum's terms
            din = []
            for src, j in p.din_sources:
                ks = k[src.inst.name]
                if ks == kt:
                    din.append((src, j))
                    continue
                h = self._held(p, src)
                self.discrete.append((h, src, j, math.lcm(ks, kt), p))
                din.append((h, j))
            p.din_sources = din
        self._attached = True

    def _routed(self, p, sources: list) -> list:
        """(input position, source, position) entries of port p, those
        across rates through held copies (libcosim's transfer at the lcm of
        both rates; an OSP Sum feeds one simulator, so its terms pass so too)."""
        k, kt = self.k, self.k[p.inst.name]
        new = []
        for pos, src, j in sources:
            ks = k[src.inst.name]
            if ks == kt:
                new.append((pos, src, j))
                continue
            h = self._held(p, src)
            self.real.append((h, src, j, math.lcm(ks, kt), p))
            new.append((pos, h, j))
        return new

    def _held(self, target, src) -> _Held:
        key = (id(target), id(src))
        h = self.held.get(key)
        if h is None:
            h = self.held[key] = _Held(src)
        return h

    def _fill_all(self) -> None:
        for h, src, j, _, _ in self.real:
            h.out[j] = src.out[j]
        for h, src, j, _, _ in self.discrete:
            h.dout[j] = src.dout[j]

    def detach(self) -> None:
        """Every link back to its source (before Initialization Mode, where
        values pass at once)."""
        if not self._attached:
            return
        for p in self.master.ports.all:
            p.sources, p.adds = ([(pos, src, j) if not isinstance(src, _Held) else (pos, self._source_of(src), j)
                                  for pos, src, j in entries] for entries in (p.sources, p.adds))
            p.din_sources = [(src, j) if not isinstance(src, _Held) else (self._source_of(src), j)
                             for src, j in p.din_sources]
        self.real.clear()
        self.discrete.clear()
        self.held.clear()
        self.starts.clear()
        self._attached = False

    def _source_of(self, held: _Held):
        return self.master.ports[held.inst.name]

    def start(self) -> None:
        """At the start of a run (after initialization): the count from 0,
        the held values those of now."""
        self.count = 0
        self.attach()

    def _pass(self, n: int) -> None:
        """The values along the links whose ends share base step n."""
        for h, src, j, every, _ in self.real:
            if n % every == 0:
                h.out[j] = src.out[j]
        for h, src, j, every, _ in self.discrete:
            if n % every == 0:
                h.dout[j] = src.dout[j]

    # -- a checkpoint's share (engine/checkpoints.py) ---------------------

    def snapshot(self) -> tuple:
        """Where each component of another rate stands and what the links
        across rates hold, for a rollback."""
        return (self.count, dict(self.starts),
                [(h, list(h.out), list(h.dout), h.out_time, list(h.d1), list(h.d2), [list(x) for x in h.past])
                 for h in self.held.values()])

    def restore(self, snap: tuple) -> None:
        self.count, starts, held = snap
        self.starts.update(starts)
        for h, out, dout, out_time, d1, d2, past in held:
            h.out[:], h.dout[:], h.out_time, h.d1[:], h.d2[:] = out, dout, out_time, d1, d2
            h.past[:] = [list(x) for x in past]

    def land(self) -> None:
        """Only TimedMultiRate lands components on an event."""
        raise AssertionError("an event located across rates without TimedMultiRate")

    # -- the step ---------------------------------------------------------

    def step(self, h: float) -> float:
        """One base step from the master's t (h must be master.step): the
        components whose own step ends at t + h take it. Returns h."""
        m = self.master
        s = m.settings
        t = m.t
        base = s.step
        if abs(h - base) > 1e-9 * base:
            raise off_base_step(t, h, base)
        self._no_events_inside(t, h)
        self.advance(t, h)
        m.stats.steps += 1
        if m.ports.diverged(s.divergence_limit):
            m.ports.name_divergence(m.t, s.divergence_limit, last_point=t)
        if m.on_step is not None:
            m.on_step(m)
        return h

    def _no_events_inside(self, t: float, h: float) -> None:
        """Refuse an announced time event or an input event inside the step
        from t of h s: a slow component would not land on it."""
        m = self.master
        base = m.settings.step
        for ev in m.time_events:
            if ev.terminated:
                raise m._asked_to_end()
            if t < ev.next_event_time < t + h and not math.isclose(ev.next_event_time, t + h):
                raise time_event_inside(t, ev.next_event_time, base)
        inputs = m.file_inputs
        if inputs is not None:
            te = inputs.samples.next_event(t)
            if t < te < t + h and not math.isclose(te, t + h):
                raise sample_event_inside(t, te, base)

    def advance(self, t: float, h: float) -> None:
        m = self.master
        ports = m.ports
        n = self.count
        t_new = t + h
        inputs = m.file_inputs
        k = self.k
        due = self.due[n % self.period] if self.due is not None else self._due(n)
        if inputs is not None:  # sampled inputs at t for what steps from t, at each slow step's start for it
            inputs.set(ports.first, t, True)
            inputs.set(self.fast_dynamic, t, True)
        # 1. Feedthrough-only instances (all at the base rate) commit the mode decided at t.
        for p in ports.first:
            st = p.doStep(p.comp, t, h, 1)
            if st > WARNING:
                raise m._step_failure(p, st, t, h)
        if inputs is not None:
            inputs.set(ports.first, t_new, False, True)
        # 2. The dynamic instances whose own step ends at t + h, each from its own start.
        set_inputs = m.coupling.set_inputs
        jacobi = m._jacobi
        starts = self.starts
        for p in self.slow:  # a slow step starts here: its start is this communication point
            if n % k[p.inst.name] == 0:
                starts[id(p)] = t
        if jacobi:
            for p in due:
                if p.has_inputs:
                    start, own = (t, h) if k[p.inst.name] == 1 else self._own_step(p, t_new)
                    set_inputs(p, start, own, False)
        last = due[-1] if due else None
        for p in due:
            kp = k[p.inst.name]
            start, own = (t, h) if kp == 1 else self._own_step(p, t_new)
            if kp != 1 and inputs is not None:
                inputs.set((p,), start, True)
            if not jacobi and p.has_inputs:
                set_inputs(p, start, own, False)
            st = p.doStep(p.comp, start, own, 1)
            if st > WARNING:
                raise m._step_failure(p, st, start, own)
            if inputs is not None and kp == 1:
                inputs.set((p,), t_new, False, True)
            p.read(t_new)
            if not jacobi and p is not last:
                ports.propagate(self.updates_after[id(p)], t_new)
        # 3. What the slow ones gave passes on, then outputs at t + h in
        # dependency order, then what those gave passes on too.
        self.count = n + 1
        self._pass(n + 1)
        m.t = t_new
        for p in ports.final_order:
            p.pull(t_new)
        self._pass(n + 1)


class TimedMultiRate(MultiRate):
    """Multi-rate stepping that keeps the master's accurate step (event
    location, extrapolation): steps of any length up to the next base grid
    point, a slow component due where a step ends at its own next point.

    - Across rates, each link passes the source's value with its polynomial
      there (the source FMU's output derivatives where it offers them, else
      divided differences through the values passed before), at the points
      both ends share; a target extrapolates it over its own step (a slow
      one from its step's start, a fast one from the slow source's last
      point on).
    - An event located in a step (indicators at the base rate only, see
      ``problem``) rolls back what stepped (checkpoints hold this stepping's
      state too); then every slow component takes a short step from its own
      start to the event, every link passes, and each starts its next step
      there, ending at its next point of start + m * k * master.step.
    """

    def __init__(self, master, rates: dict[str, int]):
        super().__init__(master, rates)
        self.ends: dict[int, float] = {}  # id(slow port) -> where its step now under way ends, s
        self.rough: dict[int, bool] = {}  # id(slow port) -> its step started at a discontinuity
        self.derivatives: dict[tuple[int, int], tuple] = {}  # (id(source), output) -> derivative_source
        self.at_point = {id(p): True for p in master.ports.dynamic}  # filled per step in advance
        master.advance = self.advance
        master.record_history = self.record_history

    def start(self) -> None:
        from .coupling import derivative_source
        m = self.master
        super().start()
        t = m.t
        for p in self.slow:
            self.starts[id(p)] = t
            self.ends[id(p)] = self._next_end(p, t)
            self.rough[id(p)] = True
        self.derivatives = {}
        if m.coupling.order:
            for _, src, j, _, _ in self.real:
                found = derivative_source(src, j)
                if found is not None:
                    self.derivatives[(id(src), j)] = found
        for h in self.held.values():
            for past in h.past:
                past.clear()
        self._pass(t)

    def _next_end(self, p, t: float) -> float:
        """The next point of p's own grid after t, s (as run_until makes its grid points)."""
        m = self.master
        k = self.k[p.inst.name]
        base = m.settings.step
        i = math.floor((t - m.start_time) / (k * base) + 1e-9) + 1
        return m.start_time + (i * k) * base

    def _at(self, p, t: float) -> bool:
        """Whether p stands at a point of its own at t (a fast one always)."""
        return self.k[p.inst.name] == 1 or self.starts.get(id(p), t) == t

    def snapshot(self) -> tuple:
        return super().snapshot(), dict(self.ends), dict(self.rough)

    def restore(self, snap: tuple) -> None:
        base, ends, rough = snap
        super().restore(base)
        self.ends.update(ends)
        self.rough.update(rough)
        for p in self.slow:  # its outputs are those of its own last point
            p.out_time = self.starts[id(p)]

    def step(self, h: float) -> float:
        """The master's accurate step (Master.step) from t, of at most h s
        and not past the next base grid point."""
        m = self.master
        t = m.t
        base = m.settings.step
        grid = m.start_time + (math.floor((t - m.start_time) / base + 1e-9) + 1) * base
        if t + h > grid + 1e-9 * base:
            raise UsageError(f"a step of {h!r} s from t = {t!r} s passes the base grid point {grid!r} s: "
                             f"components step at different rates, each a multiple of master.step ({base!r} s)")
        self._no_events_inside(t, h)
        return type(m).step(m, h)

    def _pass(self, t: float) -> None:
        """The values (and polynomials) along the links whose ends both stand at a point at t."""
        at = self._at
        order = self.master.coupling.order
        for h, src, j, _, target in self.real:
            if at(src, t) and at(target, t):
                x = h.out[j] = src.out[j]
                h.out_time = t
                if order:
                    h.d1[j], h.d2[j] = self._polynomial(h, src, j, t, x, order)
        for h, src, j, _, target in self.discrete:
            if at(src, t) and at(target, t):
                h.dout[j] = src.dout[j]

    def _polynomial(self, h: _Held, src, j: int, t: float, x: float, order: int) -> tuple[float, float]:
        """(du/dt, d2u/dt2) of source output j at t, where it has the value x."""
        from .coupling import divided_differences
        found = self.derivatives.get((id(src), j))
        if found is not None:
            inst, vrs, orders, out, m = found
            m = min(m, order)
            if inst.c_getOutputDerivatives(inst.component, vrs, m, orders, out) <= WARNING:
                return out[0], (out[1] if m == 2 else 0.0)
        past = [pt for pt in h.past[j] if pt[0] < t]
        d = divided_differences(past[-order:] + [(t, x)], order)
        past.append((t, x))
        h.past[j] = past[-3:]
        return d

    def advance(self, t: float, h: float, coupling: dict | None = None) -> None:
        """Master.advance across rates: the base-rate components from t to
        t + h, and each slow one whose own step ends at t + h from its start."""
        if coupling is not None:
            raise AssertionError("strong coupling across rates")
        m = self.master
        ports = m.ports
        loc = m.locator
        k = self.k
        t_new = t + h
        tol = 1e-9 * m.settings.step
        no_set_prior = 0 if m.checkpoints.held else 1
        inputs = m.file_inputs
        if inputs is not None:
            inputs.set(ports.first, t, True)
            inputs.set(self.fast_dynamic, t, True)
        m._commit_first(t, h, no_set_prior)  # 1. (all of them at the base rate)
        # 2. The dynamic instances whose own step ends at t + h, each from its own start.
        starts, ends = self.starts, self.ends
        due = [p for p in ports.dynamic if k[p.inst.name] == 1 or t_new >= ends[id(p)] - tol]
        set_inputs = m.coupling.set_inputs
        smooth = not m.after_event
        jacobi = m._jacobi

        def own(p):  # (start, step, smooth) of p's step ending at t + h
            if k[p.inst.name] == 1:
                return t, h, smooth
            start = starts[id(p)]
            return start, t_new - start, not self.rough[id(p)]

        if jacobi:
            for p in due:
                if p.has_inputs:
                    set_inputs(p, *own(p))
        last = due[-1] if due else None
        for p in due:
            start, step, smooth_p = own(p)
            slow = k[p.inst.name] != 1
            if slow and inputs is not None:
                inputs.set((p,), start, True)
            if not jacobi and p.has_inputs:
                set_inputs(p, start, step, smooth_p)
            st = p.doStep(p.comp, start, step, no_set_prior)
            if st > WARNING:
                raise m._step_failure(p, st, start, step)
            if inputs is not None and not slow:
                inputs.set((p,), t_new, False, True)
            p.read(t_new)
            if slow:
                starts[id(p)], ends[id(p)], self.rough[id(p)] = t_new, self._next_end(p, t_new), False
            if not jacobi and p is not last:
                ports.propagate(self.updates_after[id(p)], t_new)
        # 3. What passes at t + h, outputs at t + h in dependency order, and what those gave.
        m.t = t_new
        self._pass(t_new)
        for p in ports.final_order:
            p.pull(t_new)
        self._pass(t_new)
        if m._locating:
            loc.z_end = loc.indicators()

    def land(self) -> None:
        """After an event located at the master's t: every slow component
        steps from its own start to it, then every link passes."""
        m = self.master
        t = m.t
        inputs = m.file_inputs
        no_set_prior = 0 if m.checkpoints.held else 1
        stepped = False
        for p in self.slow:
            start = self.starts[id(p)]
            if start < t:
                if inputs is not None:
                    inputs.set((p,), start, True)
                if p.has_inputs:
                    m.coupling.set_inputs(p, start, t - start, not self.rough[id(p)])
                st = p.doStep(p.comp, start, t - start, no_set_prior)
                if st > WARNING:
                    raise m._step_failure(p, st, start, t - start)
                p.read(t)
                stepped = True
            self.starts[id(p)], self.ends[id(p)], self.rough[id(p)] = t, self._next_end(p, t), True
        for h in self.held.values():  # the polynomials start anew after the event
            for past in h.past:
                past.clear()
        self._pass(t)
        if stepped:
            for p in m.ports.final_order:
                p.pull(t)
            self._pass(t)
            if m._locating:
                m.locator.z_end = m.locator.indicators()

    def record_history(self) -> None:
        """Master.record_history: the input history of each component at its own points."""
        m = self.master
        t = m.t
        after = m.after_event_step or m.after_event
        if after:  # what was passed before a discontinuity says nothing after it
            for h in self.held.values():
                for j, past in enumerate(h.past):
                    h.past[j] = [pt for pt in past if pt[0] >= t]
        if m.coupling.order:
            m.coupling.record(t, after, [p for p in m.ports.dynamic if self._at(p, t)])


def check_rates(rates: dict[str, int] | None, instances) -> dict[str, int] | None:
    """`rates` ({instance: decimation factor}) checked against the
    instances; None where every component steps at the base step."""
    if not rates:
        return None
    for name, k in rates.items():
        if name not in instances:
            raise SceneError(f"rates: no instance {name!r}; the instances are {', '.join(instances)}")
        if isinstance(k, bool) or not isinstance(k, int) or k < 1:
            raise SceneError(f"rates: {name}: expected a whole number of base steps >= 1, got {k!r}")
    return dict(rates) if is_multirate(rates) else None
