"""Marks: the plan of ``Master.run_marks``, the engine's one driver for a
run that puts communication points at times of its own and reacts to
outputs that change.

A run to marks steps toward its stop time with steps of at most
``max_step`` (``master.step`` unless given) and

- lands a communication point on each mark (``times``, in increasing
  order); at a mark it may give the ``inputs`` a value (``sets[k]``: a
  piecewise-constant drive of unconnected inputs) or record a row of the
  ``outputs`` (``record_at_marks``);
- records a row at each point where a ``watched`` output changed (an FMU's
  event seen at a communication point), and returns there when
  ``stop_at_change``;
- once no mark lies ahead, steps ``margin`` s at a time (a point soon
  after an event that is expected but not yet seen);
- moves its mark along an event time it watches (``follow``): where a
  watched output that holds the time of an FMU's last periodic event (a
  clock's tick) changes to tt, the mark becomes tt + the last interval
  between two such events (``period`` until two are known) + ``margin``.

A row is (t, the ``outputs`` at t..., the ``before`` outputs at the point
before t...; at a mark reached without a step, before the last step the
plan took). Both engines run the same loop (``Master.run_marks``, and in
C ``cw_run_marks``, which returns to Python only when its row buffer is
full, at a stop or when its slice of wall time is spent). What the rows
mean belongs to the analysis that asked for them
(analyses/hoyng/long_run.py: a long run's tick points, the twins' replay).
"""

from __future__ import annotations

from collections.abc import Sequence

import math
import numbers

from ..errors import UsageError

ROWS_PER_CALL = 4096  # rows handed over at once (the compiled core's buffer)


def _time(where: str, value, finite: bool = True, positive: bool = False, none: bool = True):
    if value is None and none:
        return None
    ok = isinstance(value, numbers.Real) and not isinstance(value, bool) and not math.isnan(value)
    ok = ok and (math.isfinite(value) or not finite) and (value > 0 if positive else value >= 0 or not finite)
    if not ok:
        kind = "a time > 0 in s" if positive else "a time in s"
        raise UsageError(f"Marks({where} = {value!r}): expected {kind}{'' if not finite else ' (a finite number)'}")
    return float(value)


def _reals(where: str, values, what: str) -> list[float]:
    """A list of real numbers (not strings or flags), as floats."""
    try:
        out = list(values)
    except TypeError:
        out = None
    if out is None or not all(isinstance(x, numbers.Real) and not isinstance(x, bool) for x in out):
        raise UsageError(f"Marks({where}): expected {what}")
    return [float(x) for x in out]


def _flags(where: str, values) -> list[bool]:
    try:
        out = list(values)
    except TypeError:
        out = None
    if out is None or not all(x is True or x is False or type(x).__name__ == "bool_"
                              or (isinstance(x, numbers.Integral) and x in (0, 1)) for x in out):
        raise UsageError(f"Marks({where}): expected a list of flags (true or false), one per mark")
    return [bool(x) for x in out]


def _pairs(where: str, pairs, kind: str) -> list[tuple]:
    try:
        out = [tuple(x) for x in pairs]
    except TypeError:
        out = None
    if out is None or any(len(x) != 2 or isinstance(x[1], bool) or not isinstance(x[1], numbers.Integral)
                          for x in out):
        raise UsageError(f"Marks({where}): expected a list of ({kind}, whole number) pairs")
    return [(a, int(b)) for a, b in out]


class Marks:
    """Where ``Master.run_marks`` puts communication points, what it
    watches and what it records (see the module's docstring).

    Args:
        times: The marks, s: finite, in increasing order (equal neighbours
            allowed: both act at one point).
        sets: Per mark, whether it gives the `inputs` a value; None: no
            mark does.
        values: Per mark, the value given to every input where ``sets``.
        record_at_marks: Whether a mark that sets nothing records a row of
            the `outputs`.
        inputs: (instance, value reference) pairs of unconnected Real inputs.
        outputs: (port, position in ``port.out``) pairs: a row's values at
            its point.
        before: (port, position) pairs: a row's values at the point before.
        watched: (port, position) pairs: a row at each point where one of
            them changed (NaN counts as a change).
        stop_at_change: Return at the first point where a watched output
            changed.
        follow: (position in `watched`, period in s): that watched output is
            the time of an FMU's last periodic event; at most one mark may be
            given, none that sets, and each event moves it (a time <= 0 is
            no event yet).
        margin: s: the step while no mark lies ahead (None: ``max_step``).
        max_step: The longest step, s (None: ``master.step``; may be inf:
            one step to each mark).
        tolerance: A mark less than this ahead counts as reached, s (None:
            1e-12 * max(1, |t_stop|), as ``run_until`` treats its grid; 0:
            marks are exact, reached by a step aimed at them).
    """

    def __init__(self, times: Sequence[float] = (), *, sets: Sequence[bool] | None = None,
                 values: Sequence[float] | None = None, record_at_marks: bool = False,
                 inputs: Sequence[tuple] = (), outputs: Sequence[tuple] = (), before: Sequence[tuple] = (),
                 watched: Sequence[tuple] = (), stop_at_change: bool = False, follow: tuple | None = None,
                 margin: float | None = None, max_step: float | None = None, tolerance: float | None = None):
        times = _reals("times", times, "a list of times in s")
        if any(not math.isfinite(x) for x in times) or any(b < a for a, b in zip(times, times[1:])):
            raise UsageError("Marks(times): expected finite times in s, in increasing order")
        self.times = times
        n = len(times)
        if sets is None:
            self.sets = [False] * n
            self.values = [0.0] * n
        else:
            self.sets = _flags("sets", sets)
            self.values = _reals("values", () if values is None else values, "a list of numbers, one per mark")
            if len(self.sets) != n or len(self.values) != n:
                raise UsageError(f"Marks(sets, values): expected one of each per mark ({n}), "
                                 f"got {len(self.sets)} and {len(self.values)}")
        self.record_at_marks = bool(record_at_marks)
        self.inputs = _pairs("inputs", inputs, "instance")
        self.outputs = _pairs("outputs", outputs, "port")
        self.before = _pairs("before", before, "port")
        self.watched = _pairs("watched", watched, "port")
        self.stop_at_change = bool(stop_at_change)
        self.margin = _time("margin", margin, positive=True)
        self.max_step = _time("max_step", max_step, finite=False, positive=True)
        self.tolerance = _time("tolerance", tolerance)
        if follow is not None:
            try:
                index, period = follow
            except (TypeError, ValueError):
                raise UsageError("Marks(follow): expected (position in watched, period in s)") from None
            if isinstance(index, bool) or not isinstance(index, numbers.Integral) \
                    or not 0 <= index < len(self.watched):
                raise UsageError(f"Marks(follow): position {index!r} is not one of the {len(self.watched)} "
                                 "watched outputs")
            follow = (int(index), _time("follow period", period, positive=True, none=False))
            if self.margin is None or n > 1 or any(self.sets):
                raise UsageError("Marks(follow): needs a margin and at most one mark, which sets nothing "
                                 "(the events move it)")
        self.follow = follow
        # The run's own state, kept across calls (a run may be called in chunks).
        self.next = 0  # the first mark not yet reached
        self.seen: list[float] | None = None  # the watched values at the last row (or the first call)
        self.previous: list[float] = []  # the `before` outputs before the last step (or at the first call)
        self.last_event = 0.0  # follow: the event time at the last change, s
        self.prev_event: float | None = None  # and the one before, once known
        self.rows: list[tuple] = []  # rows not handed over yet (run_marks without on_rows keeps them here)
        self.rows_per_call = ROWS_PER_CALL

    def start(self) -> None:
        """At the first run: the watched and `before` outputs as they are."""
        if self.seen is None:
            self.seen = [p.out[j] for p, j in self.watched]
            self.previous = [p.out[j] for p, j in self.before]
            if self.follow is not None:
                self.last_event = self.seen[self.follow[0]]
