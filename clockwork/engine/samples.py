"""Inputs driven from samples: signals given as values at times (an input
file, fmpy's ``input=`` array), set on FMU inputs at communication points.

The values between samples follow fmpy's ``Input`` (fmpy 0.3.32,
``fmpy.simulation.Input.interpolate``), so that an FMU driven here and by
fmpy sees the same numbers:

- a *continuous* signal (a Real input of continuous variability) is
  interpolated linearly between samples; a *discrete* one (any other input)
  holds a sample's value until the next;
- before the first sample time a signal has its first value, after the
  last its last value;
- a time given in two or more rows is a step: at that time the value
  *before* the event is the first of those rows', *after* it the last's; a
  discrete signal changes at the row where its value changes, the held
  value before, the new one after;
- times are compared as ``math.isclose`` compares them (relative 1e-9), so
  a communication point that close to a sample time is at it.

Steps and changes of discrete signals are the input events: the master ends
a communication step at each (``Samples.next_event``) and treats it as a
discontinuity. Before an instance steps from t, its inputs get their values
at t after an event there; before its outputs are read at the step's end,
their values there before an event. So an output with direct feedthrough
agrees with its inputs at every communication point, while the step itself
sees what fmpy gives it (fmpy reads outputs with the inputs of the step's
start: a feedthrough output is one step late there).

``FileInputs`` binds the signals to the instances' input variables; Real
inputs are set through the same fmi2SetReal the master uses for links (the
compiled core has a twin of ``Samples.at`` in cw_inputs.c), other types
through the instance's typed setters.
"""

from __future__ import annotations

import math
from array import array
from bisect import bisect_left, bisect_right
from ctypes import c_double, c_uint
from dataclasses import dataclass

from ..errors import UsageError
from ..fmi.description import TEXT_TYPES
from ..fmi.calls import WARNING


def isclose(a: float, b: float) -> bool:
    """fmpy's test for "the same time": math.isclose, relative 1e-9 (cw_isclose in C)."""
    return math.isclose(a, b)


def is_continuous(variable) -> bool:
    """An input that is interpolated (else held): a Real of continuous variability,
    as fmpy decides (anything but "discrete" and "tunable")."""
    return variable.type in ("Real", "Float64", "Float32") and variable.variability not in ("discrete", "tunable")


@dataclass(frozen=True)
class Signal:
    """One input's samples: `values` (one per sample time) in the variable's
    own unit; floats for Real inputs, ints for integer types and
    Enumerations, bools for Booleans."""

    instance: str
    variable: str
    values: tuple
    continuous: bool

    @property
    def name(self) -> str:
        return f"{self.instance}.{self.variable}"


class Samples:
    """Sample times (s, non-decreasing) and the signals sampled at them."""

    def __init__(self, times, signals):
        # An array of doubles is taken as it is (a list of floats costs 4 times its memory).
        times = times if isinstance(times, array) and times.typecode == "d" else array("d", map(float, times))
        if not times:
            raise UsageError("input samples: expected at least one sample time")
        for k, t in enumerate(times):
            if not math.isfinite(t):
                raise UsageError(f"input samples: time {t!r} (sample {k}): expected a finite time in s")
            if k and t < times[k - 1]:
                raise UsageError(f"input samples: time {t!r} (sample {k}) is before {times[k - 1]!r}: "
                                 "expected times that never decrease")
        self.times = times
        self.signals: tuple[Signal, ...] = tuple(signals)
        for s in self.signals:
            if len(s.values) != len(times):
                raise UsageError(f"input samples: {s.name} has {len(s.values)} values for {len(times)} times")
        self.events = self._events()

    def _events(self) -> tuple[float, ...]:
        """The input events (fmpy's Input.findEvents, without its infinity):
        times given twice, and where a discrete signal changes."""
        t, n = self.times, len(self.times)
        found = set()
        if n >= 2:
            found.update(t[i] for i in range(n - 1) if t[i + 1] == t[i])
            for s in self.signals:
                if not s.continuous:
                    found.update(t[i + 1] for i in range(n - 1) if s.values[i + 1] != s.values[i])
        return tuple(sorted(found))

    def next_event(self, t: float) -> float:
        """The first input event after t that is not at t (fmpy's
        Input.nextEvent), else infinity."""
        events = self.events
        for i in range(bisect_right(events, t), len(events)):
            if not isclose(events[i], t):
                return events[i]
        return math.inf

    def event_at(self, t: float) -> bool:
        """Whether an input event is at t."""
        events = self.events
        i = bisect_left(events, t)
        return any(isclose(events[j], t) for j in (i - 1, i) if 0 <= j < len(events))

    def at(self, time: float, after_event: bool) -> list:
        """Every signal's value at `time`: after an event there when
        `after_event`, else before it (fmpy's Input.interpolate, the same
        operations in the same order)."""
        t, n = self.times, len(self.times)
        signals = self.signals
        if n < 2:
            return [s.values[0] for s in signals]
        i0 = bisect_left(t, time)
        if i0 == 0:
            return [s.values[0] for s in signals]
        if i0 == n:
            return [s.values[-1] for s in signals]
        held = i0 - 1  # discrete signals: the last sample at or before the time
        if after_event:
            while held + 1 < n and (t[held + 1] < time or isclose(time, t[held + 1])):
                held += 1
        row = -1  # continuous signals at a step: the row to take
        if isclose(time, t[i0]) and i0 < n - 1 and isclose(t[i0], t[i0 + 1]):
            row = i0
            if after_event:
                while row < n - 1 and isclose(t[row], t[row + 1]):
                    row += 1
        else:
            t0, t1 = t[i0 - 1], t[i0]
            w0 = (t1 - time) / (t1 - t0)
            w1 = 1 - w0
        out = []
        for s in signals:
            v = s.values
            if not s.continuous:
                out.append(v[held])
            elif row >= 0:
                out.append(v[row])
            else:
                out.append(w0 * v[i0 - 1] + w1 * v[i0])
        return out


class FileInputs:
    """Samples bound to the inputs of a system's instances, set by the master.

    Real inputs (per instance, one fmi2SetReal call) are in ``real``:
    instance name -> (signal indices, value references, value array);
    inputs of other types in ``typed``: instance name -> [(signal index, variable)].
    """

    def __init__(self, samples: Samples, instances: dict, connected: set[tuple[str, str]] = frozenset()):
        self.samples = samples
        self.real: dict[str, tuple[list[int], object, object]] = {}
        self.typed: dict[str, list[tuple[int, str]]] = {}
        for j, s in enumerate(samples.signals):
            inst = instances.get(s.instance)
            if inst is None:
                raise UsageError(f"input samples: {s.name}: no instance {s.instance!r}; the instances are "
                                 f"{', '.join(instances) or 'none'}")
            v = inst.variables.get(s.variable)
            if v is None:
                raise UsageError(f"input samples: {s.name}: {inst.model_name} has no variable {s.variable!r}")
            if v.causality != "input":
                raise UsageError(f"input samples: {s.name}: expected an input, {s.variable} is a {v.causality}")
            if (s.instance, s.variable) in connected:
                raise UsageError(f"input samples: {s.name} is connected: an input is either connected or "
                                 "driven from samples")
            if v.type in TEXT_TYPES:
                raise UsageError(f"input samples: {s.name} is a {v.type}: samples drive numbers and Booleans")
            if v.type == "Real":
                self.real.setdefault(s.instance, ([], [], None))[0].append(j)
                self.real[s.instance][1].append(v.vr)
            else:
                self.typed.setdefault(s.instance, []).append((j, s.variable))
        for name, (cols, vrs, _) in self.real.items():
            self.real[name] = (cols, (c_uint * len(vrs))(*vrs), (c_double * len(vrs))())
        self._last: tuple | None = None  # (time, after_event, values): the three calls of a step share two
        # Instances whose outputs may not be read after their inputs are set
        # without a step: their inputs are not set again after their step.
        self.held = {n for n, inst in instances.items() if not getattr(inst, "outputs_after_inputs", True)}

    def non_real(self) -> list[str]:
        """The inputs driven here that are not Real ("instance.variable")."""
        return [f"{name}.{var}" for name, pairs in self.typed.items() for _, var in pairs]

    def _values(self, t: float, after_event: bool) -> list:
        last = self._last
        if last is not None and last[0] == t and last[1] == after_event:
            return last[2]
        values = self.samples.at(t, after_event)
        self._last = (t, after_event, values)
        return values

    def set(self, ports, t: float, after_event: bool, after_step: bool = False) -> None:
        """Set the driven inputs of these ports' instances to their values at
        t. `after_step`: t is the end of the step they just took, and their
        outputs are read next (left out where that read is not allowed: the
        next step starts from the inputs at its start)."""
        values = None
        for p in ports:
            name = p.inst.name
            real = self.real.get(name)
            typed = self.typed.get(name)
            if real is None and typed is None or after_step and name in self.held:
                continue
            if values is None:
                values = self._values(t, after_event)
            if real is not None:
                cols, vrs, buf = real
                for k, j in enumerate(cols):
                    buf[k] = values[j]
                st = p.setReal(p.comp, vrs, len(cols), buf)
                if st > WARNING:
                    raise p.inst.fail(p.inst.named("setReal") + " of inputs", st, t)
            if typed is not None:
                p.inst.set_values({var: values[j] for j, var in typed}, "setting sampled inputs")
