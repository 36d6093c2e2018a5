"""FMI 3.0 clocks across FMUs: the ticks, their events and their records.

A scene with an FMU that has clocks (fmi/clocks.py) runs on ``ClockedMaster``,
the Python master with the clock schedule around its step; a scene without
clocks never reaches this module (``make_master`` picks the plain master).

- **Input clocks the master drives.** A periodic clock (``constant``:
  interval and shift from the description; ``fixed``, ``calculated``,
  ``tunable``: asked of the FMU after initialization; ``changing``: asked
  again after each tick) ticks at start + shift + k * interval (drift-free
  for the first three); a countdown clock ticks the interval the FMU set
  (qualifier fmi3IntervalChanged) after the event where it set it; a
  triggered input clock ticks when a connected output clock ticks, or at
  each row of the input file whose column named after it is non-zero. The
  step is cut so that a communication point lands on every tick.
- **The event at a tick.** At a communication point with ticks, each FMU
  with a ticking clock is visited in the order the clock connections give
  (a source before its targets): a Co-Simulation FMU enters Event Mode,
  its input clocks are set (fmi3SetClock), its clocked inputs get their
  sources' newest values, its output clocks are read (fmi3GetClock) and
  their ticks routed to the connected input clocks (of FMUs visited later
  in the same event), its clocked outputs are read, fmi3UpdateDiscreteStates
  runs until the discrete states settle, the countdown and changing
  intervals are asked, and it enters Step Mode again. A Scheduled Execution
  FMU gets fmi3ActivateModelPartition for each of its ticking input clocks,
  in the order of their priorities (the smallest number first), its clocked
  inputs set before and its clocked outputs read after each; when the FMU
  calls clockUpdate, its output clocks and countdown intervals are asked.
- **Events the FMU signals** (an output clock that ticks by itself: a Co-
  Simulation FMU returns ``eventHandlingNeeded`` from fmi3DoStep): handled
  there (``Instance3.clock_event``), its output clocks' ticks routed at the
  communication point that ends the step. A tick inside a step (early
  return) reaches the connected clocks at that communication point: said
  once in a note, with how late it came.
- **Records.** Each clock's tick times and each clocked output's value
  after each of its ticks (``ticks``, ``clocked``), apart from the
  communication points' series. Clocked variables are exchanged only at
  their clocks' ticks: never per step.

On the compiled core (engine/compiled_clocks.py) the steps are C's, which
land on the ticks and stop where an event is due; the event is this
module's, through ``at_point``.
"""

from __future__ import annotations

import math

from ..errors import SceneError, SimulationError, UsageError
from ..fmi.clocks import INTERVAL_CHANGED, INTERVAL_NOT_YET_KNOWN, RETUNED, Clock, ClockTable, clock_table
from ..fmi.scheduled import ClockCalls
from .master import Master
from .samples import Samples, isclose
from .wiring import Link

MAX_EVENT_ROUNDS = 100  # visits of the FMUs in one event before the clock connections count as a cycle


def clock_tables(instances) -> dict[str, ClockTable]:
    """{instance: its clocks} for the instances that have clocks."""
    tables = {}
    for name, inst in instances.items():
        table = inst.clock_table()
        if table:
            tables[name] = table
    return tables


def clocks_text(instances) -> str | None:
    """"FMI 3.0 clocks (the instances that have them)", or None without clocks."""
    names = list(clock_tables(instances))
    if not names:
        return None
    return f"FMI 3.0 clocks ({', '.join(names[:3])}{', ...' * (len(names) > 3)})"


class _Schedule:
    """When one input clock ticks next."""

    __slots__ = ("inst", "clock", "base", "interval", "k", "next")

    def __init__(self, inst: str, clock: Clock):
        self.inst, self.clock = inst, clock
        self.base = self.interval = None
        self.k = 0
        self.next = math.inf

    def periodic(self, base: float, interval: float | None) -> None:
        self.base, self.interval, self.k = base, interval, 0
        self.next = base


class ClockedMaster(Master):
    """The Python master with FMI 3.0 clocks (see the module's docstring)."""

    def __init__(self, instances, links, settings, start_time=0.0, step_order=None, extra_outputs=None,
                 inputs: Samples | None = None):
        self.tables = clock_tables(instances)
        links, extra_outputs, inputs = self._split(instances, list(links), extra_outputs, inputs)
        super().__init__(instances, links, settings, start_time, step_order, extra_outputs, inputs)
        self.calls = {n: ClockCalls(instances[n]) for n in self.tables}
        for n in self.tables:
            inst = instances[n]
            if not getattr(inst, "scheduled", False):
                inst.clock_event = self._fmu_event_handler(n)
        # The order of visits in an event: sources of clock connections first.
        self.visit_order = _clock_order(list(instances), self.clock_links)
        self.clock_ticks: dict[str, list[float]] = {}
        self.clocked_values: dict[str, list[tuple[float, object]]] = {}
        self._schedules: list[_Schedule] = []
        self._pending: list[tuple[str, str, float]] = []  # output-clock ticks the FMUs signalled: (instance, clock, t)
        # Co-Simulation FMUs with output clocks: asked in Event Mode at each
        # state event the master located (an output clock that ticks on a
        # state of the FMU's inputs, as an escapement's switch).
        self._asked = [n for n, t in self.tables.items() if not getattr(instances[n], "scheduled", False)
                       and any(c.causality == "output" for c in t.clocks.values())]
        self._late_said = False

    # -- what the scene gives ------------------------------------------------

    def _split(self, instances, links: list[Link], extra_outputs, inputs):
        """Take the clock connections, the links of clocked variables, the
        clocked recorded outputs and the input file's clock columns out of
        what the plain master gets."""
        tables = self.tables
        self.clock_links: list[Link] = []
        self.clocked_links: list[Link] = []
        plain = []
        for k in links:
            text = f"connection {k.src}.{k.output} -> {k.dst}.{k.input}"
            s_t, d_t = tables.get(k.src), tables.get(k.dst)
            s_clock = s_t is not None and k.output in s_t.clocks
            d_clock = d_t is not None and k.input in d_t.clocks
            if s_clock or d_clock:
                if not (s_clock and d_clock):
                    raise SceneError(f"{text}: a clock connects to a clock only")
                src, dst = s_t.clocks[k.output], d_t.clocks[k.input]
                if src.causality != "output" or dst.causality != "input":
                    raise SceneError(f"{text}: expected an output clock on the left and an input clock on the right")
                if dst.variability != "triggered":
                    raise SceneError(f"{text}: {k.dst}.{k.input} is a {dst.variability} clock, which the master "
                                     "ticks itself; a connection ticks a triggered input clock only")
                self.clock_links.append(k)
            elif (s_t is not None and k.output in s_t.clocked) or (d_t is not None and k.input in d_t.clocked):
                if not k.identity:
                    raise SceneError(f"{text}: a clocked variable's connection takes no linear transformation")
                self.clocked_links.append(k)
            else:
                plain.append(k)
        self._file_ticks: dict[tuple[str, str], list[float]] = {}
        if inputs is not None:
            kept = []
            for s in inputs.signals:
                t = tables.get(s.instance)
                if t is not None and s.variable in t.clocks:
                    c = t.clocks[s.variable]
                    if c.causality != "input" or c.variability != "triggered":
                        raise UsageError(f"input samples: {s.name}: a column ticks a triggered input clock; "
                                         f"{s.variable} is a {c.variability} {c.causality} clock")
                    self._file_ticks[(s.instance, s.variable)] = sorted(
                        {float(x) for x, v in zip(inputs.times, s.values) if v})
                elif t is not None and s.variable in t.clocked:
                    raise UsageError(f"input samples: {s.name} is a clocked input: the master sets it at its "
                                     "clock's ticks from a connection only")
                else:
                    kept.append(s)
            inputs = Samples(inputs.times, kept) if kept else None
        self.recorded: dict[str, list[str]] = {}
        if extra_outputs:
            rest = {}
            for n, names in extra_outputs.items():
                t = tables.get(n)
                if t is None:
                    rest[n] = names
                    continue
                rest[n] = [x for x in names if x not in t.clocks and x not in t.clocked]
            extra_outputs = rest
        return plain, extra_outputs, inputs

    # -- initialization ---------------------------------------------------------

    def initialize(self, parameters) -> None:
        super().initialize(parameters)
        self.clock_ticks = {f"{n}.{c}": [] for n, t in self.tables.items() for c in t.clocks}
        self.clocked_values = {f"{n}.{v}": [] for n, t in self.tables.items() for v, c in t.causality.items()
                        if c == "output"}
        self._latest: dict[tuple[str, str], object] = {}
        self._pending = []
        self._schedules = []
        t0 = self.t
        for n, table in self.tables.items():
            calls = self.calls[n]
            for c in table.clocks.values():
                if c.causality != "input":
                    continue
                s = _Schedule(n, c)
                if c.variability == "constant":
                    s.periodic(t0 + c.shift, c.interval)
                elif c.variability in ("fixed", "calculated", "tunable"):
                    q, interval = calls.interval(c, t0)
                    interval = interval if q != INTERVAL_NOT_YET_KNOWN and interval > 0 else c.interval
                    if interval is None:
                        raise SimulationError(f"{n}.{c.name}: a {c.variability} clock whose interval the FMU "
                                              "does not give after initialization (and the description neither)",
                                              time=t0, instance=n)
                    s.periodic(t0 + calls.shift(c, t0), interval)
                elif c.variability == "changing":
                    s.periodic(t0 + calls.shift(c, t0), None)
                elif c.variability == "countdown":
                    self._countdown(s, t0)
                elif (n, c.name) in self._file_ticks:
                    s.base = self._file_ticks[(n, c.name)]
                    s.next = s.base[0] if s.base else math.inf
                else:
                    continue
                if s.interval is not None and not s.interval > 0:
                    raise SceneError(f"{n}.{c.name}: the clock's interval is {s.interval!r} s: expected > 0")
                self._schedules.append(s)
        self._event(t0)

    def _countdown(self, s: _Schedule, t: float) -> None:
        q, interval = self.calls[s.inst].interval(s.clock, t)
        if q == INTERVAL_CHANGED:
            if not interval >= 0:
                raise SimulationError(f"{s.inst}.{s.clock.name}: the FMU set the countdown interval {interval!r} s",
                                      time=t, instance=s.inst)
            s.next = t + interval

    # -- the step -------------------------------------------------------------

    def next_tick(self, t: float) -> float:
        """The earliest tick after t (not at t), s; inf when none is scheduled."""
        return min((s.next for s in self._schedules if s.next > t and not isclose(s.next, t)), default=math.inf)

    def step(self, h: float) -> float:
        t = self.t
        tick = self.next_tick(t)
        if t + h > tick and not isclose(t + h, tick):
            h = tick - t
        self._pending = []
        taken = super().step(h)
        self.at_point()
        return taken

    def at_point(self) -> None:
        """At the communication point a step reached: the event of the
        clocks there, if any (the compiled core calls it where its step
        says one is due)."""
        now = self.t
        # Ticks of discarded trials (a rollback beyond where the step ended) are forgotten.
        self._pending = [p for p in self._pending if p[2] <= now or isclose(p[2], now)]
        located = self.after_event_step and bool(self._asked)
        if located or self._pending or any(s.next <= now or isclose(s.next, now) for s in self._schedules):
            self._event(now, located)

    # -- events ---------------------------------------------------------------

    def _due(self, t: float) -> dict[str, list[str]]:
        """The input clocks due at t, by instance; their schedules moved on."""
        due: dict[str, list[str]] = {}
        for s in self._schedules:
            if s.next <= t or isclose(s.next, t):
                due.setdefault(s.inst, []).append(s.clock.name)
                if isinstance(s.base, list):  # an input file's ticks
                    s.k += 1
                    s.next = s.base[s.k] if s.k < len(s.base) else math.inf
                elif s.clock.variability == "countdown":
                    s.next = math.inf
                elif s.interval is not None:
                    s.k += 1
                    s.next = s.base + s.k * s.interval
                else:  # changing: asked after the tick
                    s.next = math.inf
        return due

    def _event(self, t: float, located: bool = False) -> None:
        """Every tick at t: the master's own, the routing of those the FMUs
        signalled, and, at a located state event, the output clocks of the
        FMUs that have them."""
        due = self._due(t)
        asked = set(self._asked) if located else set()
        for src, clock, when in self._pending:
            if when < t and not isclose(when, t) and not self._late_said:
                self._late_said = True
                self.coupling.note(f"{src}.{clock} ticked inside a step at t = {when!r} s (an early return); the "
                                   f"connected clocks ticked at the communication point t = {t!r} s", kind="note")
            self._route(src, clock, due)
        self._pending = []
        if not due and not asked:
            return
        touched = []
        self._ticked = False
        for _ in range(MAX_EVENT_ROUNDS):
            if not due and not asked:
                break
            for n in self.visit_order:
                clocks = due.pop(n, None)
                if clocks or n in asked:
                    asked.discard(n)
                    clocks = list(dict.fromkeys(clocks or ()))
                    if getattr(self.instances[n], "scheduled", False):
                        self._activate(n, clocks, t, due)
                    else:
                        self._tick(n, clocks, t, due)
                    touched.append(n)
        else:
            raise SimulationError(f"the clock connections tick each other without end at t = {t!r} s", time=t)
        if not self._ticked:  # asked at a state event, and no clock ticked: nothing changed
            return
        for n in dict.fromkeys(touched):
            p = self.ports[n]
            if p.n_out or p.dout_names:
                p.read(t)
        self._set_plain_targets(touched)
        if not self.after_event:  # at a located event the master already starts again from it
            self.discontinuity()

    def _route(self, src: str, clock: str, due: dict[str, list[str]]) -> None:
        for k in self.clock_links:
            if k.src == src and k.output == clock:
                due.setdefault(k.dst, []).append(k.input)

    def _tick(self, n: str, clocks: list[str], t: float, due) -> None:
        """An event of a Co-Simulation FMU at t with these input clocks ticking."""
        calls, table = self.calls[n], self.tables[n]
        calls.enter_event_mode(t)
        self._clock_event(n, [table.clocks[c] for c in clocks], t, due)

    def _fmu_event_handler(self, n: str):
        def handle(t: float) -> int:
            self.calls[n].enter_event_mode(t)
            self._clock_event(n, [], t, None)
            return 0
        return handle

    def _clock_event(self, n: str, inputs: list[Clock], t: float, due) -> None:
        """In Event Mode: set the ticking input clocks and their clocked
        inputs, read the output clocks and the clocked outputs, settle, ask
        the intervals, back to Step Mode. `due` None: the FMU signalled the
        event inside its step; its output ticks wait in ``_pending``."""
        calls, table, inst = self.calls[n], self.tables[n], self.instances[n]
        if inputs:
            calls.set_clocks(inputs, t)
            self._set_clocked_inputs(n, [c.name for c in inputs])
        outs = [c for c in table.clocks.values() if c.causality == "output"]
        ticked = [c for c, on in zip(outs, calls.get_clocks(outs, t)) if on]
        active = [c.name for c in inputs] + [c.name for c in ticked]
        for c in active:
            self._tick_record(f"{n}.{c}", t)
        for c in ticked:
            if due is None:
                self._pending.append((n, c.name, t))
            else:
                self._route(n, c.name, due)
        self._read_clocked_outputs(n, active, t)
        inst.events.next_event_time = calls.update_until_settled(t)
        inst.events.events += 1  # as an event the face handles itself
        self._ask_intervals(n, [c.name for c in inputs], t)
        calls.enter_step_mode(t)

    def _activate(self, n: str, clocks: list[str], t: float, due) -> None:
        """Scheduled Execution: each ticking input clock's partition, by priority."""
        calls, table, inst = self.calls[n], self.tables[n], self.instances[n]
        order = sorted((table.clocks[c] for c in clocks), key=lambda c: (c.priority, c.vr))
        outs = [c for c in table.clocks.values() if c.causality == "output"]
        for c in order:
            self._set_clocked_inputs(n, [c.name])
            before = inst.clock_updates
            calls.activate(c, t)
            self._tick_record(f"{n}.{c.name}", t)
            self._read_clocked_outputs(n, [c.name], t)
            if inst.clock_updates != before:
                ticked = [o for o, on in zip(outs, calls.get_clocks(outs, t)) if on]
                for o in ticked:
                    self._tick_record(f"{n}.{o.name}", t)
                    self._route(n, o.name, due)
                self._read_clocked_outputs(n, [o.name for o in ticked], t)
                for s in self._schedules:
                    if s.inst == n and s.clock.variability == "countdown":
                        self._countdown(s, t)
                        if s.next <= t or isclose(s.next, t):  # a zero interval: ticks in this event
                            s.next = math.inf
                            due.setdefault(n, []).append(s.clock.name)
            self._ask_intervals(n, [c.name], t, countdown=False)

    def _ask_intervals(self, n: str, ticked: list[str], t: float, countdown: bool = True) -> None:
        """After an event: the countdown intervals the FMU set, and the new
        intervals of the changing and tunable clocks that ticked."""
        for s in self._schedules:
            if s.inst != n:
                continue
            c = s.clock
            if countdown and c.variability == "countdown":
                self._countdown(s, t)
            elif c.variability in RETUNED and c.name in ticked:
                q, interval = self.calls[n].interval(c, t)
                if q == INTERVAL_CHANGED or s.interval is None:
                    if not interval > 0:
                        raise SimulationError(f"{n}.{c.name}: the FMU gave the interval {interval!r} s",
                                              time=t, instance=n)
                    s.base, s.interval, s.k = t, interval, 1
                    s.next = t + interval

    def _set_clocked_inputs(self, n: str, clocks: list[str]) -> None:
        """The clocked inputs of these clocks, from their sources' newest values."""
        table = self.tables[n]
        values = {}
        for k in self.clocked_links:
            if k.dst == n and any(c in clocks for c in table.clocked.get(k.input, ())):
                values[k.input] = self._source_value(k)
        if values:
            self.instances[n].set_values(values, "fmi3Set* of clocked inputs")

    def _source_value(self, k: Link):
        key = (k.src, k.output)
        if key in self._latest:
            return self._latest[key]
        return self.instances[k.src].get_values([k.output])[0]

    def _read_clocked_outputs(self, n: str, clocks: list[str], t: float) -> None:
        table = self.tables[n]
        names = [v for v, cs in table.clocked.items() if table.causality[v] == "output" and any(c in clocks for c in cs)]
        if not names:
            return
        for v, x in zip(names, self.instances[n].get_values(names)):
            self._latest[(n, v)] = x
            series = self.clocked_values[f"{n}.{v}"]
            if series and series[-1][0] == t:  # the same tick again (a step taken again after a rollback)
                series[-1] = (t, x)
            else:
                series.append((t, x))

    def _tick_record(self, name: str, t: float) -> None:
        self._ticked = True
        times = self.clock_ticks[name]
        if not times or times[-1] != t:
            times.append(t)

    def _set_plain_targets(self, touched: list[str]) -> None:
        """Unclocked inputs fed by clocked outputs: their sources' values after the event (held between ticks)."""
        by_dst: dict[str, dict[str, object]] = {}
        for k in self.clocked_links:
            if k.src in touched and (k.src, k.output) in self._latest and k.input not in self.tables.get(
                    k.dst, ClockTable()).clocked:
                by_dst.setdefault(k.dst, {})[k.input] = self._latest[(k.src, k.output)]
        for dst, values in by_dst.items():
            self.instances[dst].set_values(values, "fmi*Set* of inputs fed by clocked outputs")


def _clock_order(names: list[str], links: list[Link]) -> list[str]:
    """The instances with the sources of clock connections before their
    targets (Kahn's algorithm; the instances of a cycle in their own order)."""
    succ: dict[str, set[str]] = {n: set() for n in names}
    indeg = dict.fromkeys(names, 0)
    for k in links:
        if k.dst not in succ[k.src] and k.src != k.dst:
            succ[k.src].add(k.dst)
            indeg[k.dst] += 1
    order, ready = [], [n for n in names if indeg[n] == 0]
    while ready:
        n = ready.pop(0)
        order.append(n)
        for m in sorted(succ[n], key=names.index):
            indeg[m] -= 1
            if indeg[m] == 0:
                ready.append(m)
    return order + [n for n in names if n not in order]
