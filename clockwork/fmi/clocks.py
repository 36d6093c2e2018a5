"""FMI 3.0 clocks: what a description declares and the calls that serve them.

A Clock variable (FMI 3.0 section 2.4.7.1.9) is an input clock, ticked by
the importer, or an output clock, ticked by the FMU. Its
``intervalVariability`` says who knows when it ticks:

- ``constant``: every ``intervalDecimal`` s from start + ``shiftDecimal``;
- ``fixed``, ``calculated``: likewise, the interval and shift asked of the
  FMU (fmi3GetIntervalDecimal, fmi3GetShiftDecimal) after initialization;
- ``tunable``, ``changing``: periodic, the interval asked again after each
  tick (a changed one counts from that tick);
- ``countdown``: the FMU sets the interval (qualifier fmi3IntervalChanged)
  in an event or, in Scheduled Execution, in a partition that calls
  ``clockUpdate``; the clock ticks that long after;
- ``triggered``: no time is known beforehand (an output clock's tick, or an
  input clock ticked by a connected output clock or an input file).

Variables with a ``clocks`` attribute are clocked: they are exchanged only
when one of their clocks ticks.

The calls that serve them are in fmi/scheduled.py.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from fmpy.model_description import CoSimulation

INTERVAL_NOT_YET_KNOWN, INTERVAL_UNCHANGED, INTERVAL_CHANGED = 0, 1, 2
PERIODIC = ("constant", "fixed", "calculated", "tunable", "changing")
# Periodic clocks whose interval may change after a tick (asked again after each).
RETUNED = ("tunable", "changing")


@dataclass
class Clock:
    """One Clock variable of a description."""

    name: str
    vr: int
    causality: str  # "input" or "output"
    variability: str  # intervalVariability
    interval: float | None = None  # intervalDecimal, s
    shift: float = 0.0  # shiftDecimal, s
    priority: int | None = None

    @property
    def periodic(self) -> bool:
        return self.variability in PERIODIC


@dataclass
class ClockTable:
    """A description's clocks and clocked variables."""

    clocks: dict[str, Clock] = field(default_factory=dict)  # name -> Clock
    clocked: dict[str, list[str]] = field(default_factory=dict)  # variable -> the names of its clocks

    def __bool__(self) -> bool:
        return bool(self.clocks)

    def variables_of(self, clock: str, causality: str) -> list[str]:
        """The clocked variables of `causality` that tick with `clock`."""
        return [n for n, cs in self.clocked.items() if clock in cs and self.causality[n] == causality]

    causality: dict[str, str] = field(default_factory=dict)  # clocked variable -> its causality


def clock_table(md) -> ClockTable:
    """The clocks of an FMI 3.0 description (empty for other versions)."""
    table = ClockTable()
    if getattr(md, "fmiVersion", None) != "3.0":
        return table
    for v in md.modelVariables:
        if v.type == "Clock":
            table.clocks[v.name] = Clock(
                v.name, v.valueReference, v.causality, v.intervalVariability or "triggered",
                None if v.intervalDecimal is None else float(v.intervalDecimal),
                float(v.shiftDecimal or 0.0), None if v.priority is None else int(v.priority))
    for v in md.modelVariables:
        if v.type != "Clock" and v.clocks:
            table.clocked[v.name] = [c.name for c in v.clocks]
            table.causality[v.name] = v.causality
    return table


def clock_problem(md) -> str | None:
    """Why the master cannot run this FMU's clocks, or None."""
    table = clock_table(md)
    if not table:
        return None
    if md.coSimulation is None and getattr(md, "scheduledExecution", None) is None:
        return "its clocks are served in Co-Simulation and Scheduled Execution only, not in Model Exchange"
    scheduled = is_scheduled(md)
    if not scheduled and not md.coSimulation.hasEventMode:
        return "it has clocks but no Event Mode (hasEventMode), where FMI 3.0 Co-Simulation ticks them"
    for c in table.clocks.values():
        if c.causality not in ("input", "output"):
            return f"clock {c.name}: expected causality input or output, found {c.causality}"
        if c.variability == "constant" and c.causality == "input" and not (c.interval or 0) > 0:
            return f"clock {c.name}: a constant clock needs intervalDecimal > 0"
        if scheduled and c.causality == "input" and c.priority is None:
            return f"clock {c.name}: an input clock of Scheduled Execution needs a priority"
    return None


class ScheduledFace(CoSimulation):
    """The ``coSimulation`` of an FMU that has Scheduled Execution only, made
    from its ``<ScheduledExecution>`` (description._check_clocks): the layers
    that read Co-Simulation capabilities read its own; no Event Mode."""


def is_scheduled(md) -> bool:
    """An FMI 3.0 FMU that the master runs through Scheduled Execution."""
    return isinstance(md.coSimulation, ScheduledFace)




def _seconds(x: float) -> str:
    return f"{x:g} s"


def schedule_text(c: Clock) -> str:
    """When a clock ticks, in words (``clockwork info`` and ``validate``)."""
    if c.causality == "output":
        return "ticked by the FMU (an output clock), read in Event Mode and passed to the connected input clocks"
    given = f" (the description says every {_seconds(c.interval)})" if c.interval else ""
    return {
        "constant": f"every {_seconds(c.interval or 0.0)} from the start + {_seconds(c.shift)}",
        "fixed": f"periodic, interval and shift asked of the FMU after initialization{given}",
        "calculated": f"periodic, interval and shift asked of the FMU after initialization{given}",
        "tunable": f"periodic, interval asked of the FMU after initialization and after each tick{given}",
        "changing": "periodic from the start + the shift the FMU gives, each interval asked after the tick before",
        "countdown": "when an interval the FMU sets (fmi3IntervalChanged) has run out",
        "triggered": "ticked by a connected output clock, or by an input file column named after it",
    }.get(c.variability, c.variability)


def clock_lines(md, prefix: str = "") -> list[str]:
    """A description's clocks, one line each: name, causality,
    intervalVariability, priority, when it ticks, its clocked variables."""
    table = clock_table(md)
    lines = []
    for c in table.clocks.values():
        clocked = [v for v, cs in table.clocked.items() if c.name in cs]
        priority = f", priority {c.priority}" if c.priority is not None else ""
        lines.append(f"{prefix}{c.name} ({c.causality}, {c.variability}{priority}): {schedule_text(c)}; "
                     f"clocked: {', '.join(clocked) or 'none'}")
    return lines
