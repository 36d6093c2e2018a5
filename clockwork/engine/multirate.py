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

What needs every component at one time (a rollback for event location,
strong coupling, step doubling), input polynomials (extrapolation) and
algebraic loops with a slow member are refused in one line
(``problem``, ``loop_problem``) rather than done differently. A scene
whose components all step at master.step never comes here: the master
takes its single-rate path, with the same bits as before.

The compiled core's twin is src_c/master/cw_rates.c (the same bits, by
tests/test_multirate.py); what it does not do across rates is decided in
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


def problem(settings, rates: dict[str, int], indicators: dict[str, object]) -> tuple[str, str] | None:
    """What of these master settings cannot run with these decimation
    factors, as (the first slow instance, the line that says which setting
    and what was expected), or None. `indicators`: per instance, its event
    indicators (empty where it has none)."""
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
    if settings.extrapolation:
        return first, (f"master.extrapolation = {settings.extrapolation}: expected 0 (zero-order hold): {why}, and "
                       f"input polynomials across rates are not done; {alike}")
    if settings.event_location:
        located = [n for n, z in indicators.items() if z]
        if located:
            return first, (f"master.event_location = true: expected false: locating the events of "
                           f"{', '.join(located)} rolls every component back to the event, and {why}; {alike}")
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
    were at the last point both share (``out`` and ``dout`` as a Port's)."""

    __slots__ = ("inst", "out_names", "dout_names", "out", "dout")

    def __init__(self, src):
        self.inst, self.out_names, self.dout_names = src.inst, src.out_names, src.dout_names
        self.out = list(src.out)
        self.dout = list(src.dout)


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
            new = []
            for pos, src, j in p.sources:
                ks = k[src.inst.name]
                if ks == kt:
                    new.append((pos, src, j))
                    continue
                h = self._held(p, src)
                self.real.append((h, src, j, math.lcm(ks, kt)))
                new.append((pos, h, j))
            p.sources = new
            din = []
            for src, j in p.din_sources:
                ks = k[src.inst.name]
                if ks == kt:
                    din.append((src, j))
                    continue
                h = self._held(p, src)
                self.discrete.append((h, src, j, math.lcm(ks, kt)))
                din.append((h, j))
            p.din_sources = din
        self._attached = True

    def _held(self, target, src) -> _Held:
        key = (id(target), id(src))
        h = self.held.get(key)
        if h is None:
            h = self.held[key] = _Held(src)
        return h

    def _fill_all(self) -> None:
        for h, src, j, _ in self.real:
            h.out[j] = src.out[j]
        for h, src, j, _ in self.discrete:
            h.dout[j] = src.dout[j]

    def detach(self) -> None:
        """Every link back to its source (before Initialization Mode, where
        values pass at once)."""
        if not self._attached:
            return
        for p in self.master.ports.all:
            p.sources = [(pos, src, j) if not isinstance(src, _Held) else (pos, self._source_of(src), j)
                         for pos, src, j in p.sources]
            p.din_sources = [(src, j) if not isinstance(src, _Held) else (self._source_of(src), j)
                             for src, j in p.din_sources]
        self.real.clear()
        self.discrete.clear()
        self.held.clear()
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
        for h, src, j, every in self.real:
            if n % every == 0:
                h.out[j] = src.out[j]
        for h, src, j, every in self.discrete:
            if n % every == 0:
                h.dout[j] = src.dout[j]

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
        self.advance(t, h)
        m.stats.steps += 1
        if m.ports.diverged(s.divergence_limit):
            m.ports.name_divergence(m.t, s.divergence_limit, last_point=t)
        if m.on_step is not None:
            m.on_step(m)
        return h

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
