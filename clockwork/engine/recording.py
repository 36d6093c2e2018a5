"""Recording: what is kept of a run.

A ``Recorder`` is called at every communication point (``Master.run_until``'s
``on_point``). It keeps chosen outputs on the grid start + k * interval
(every grid point when no interval is given; the extra points of located
events too in that case) and the tick times of one instance (its
``tick_time`` output, which changes at each upward zero crossing).
Variables of the other types are read from the FMU when sampled (String
as text); Real ones come from the master's output buffer.

With a `sink` (results.series.SeriesWriter: any object with ``write(columns)``
and ``close()``), the rows go to it a chunk of CHUNK_VALUES values at a
time and the recorder keeps at most one chunk: a run's memory does not
grow with its length. Without one, every row is kept in ``columns``.
"""

from __future__ import annotations

from ..errors import SimulationError
from ..fmi.description import TEXT_TYPES


def _in_group(instances, instance: str, var: str) -> tuple[str, str]:
    """(instance, variable) as the master holds it: a member of a Model
    Exchange group (engine/me_group.py) is its group's "member.variable"."""
    if instance in instances:
        return instance, var
    for name, inst in instances.items():
        if any(m.name == instance for m in getattr(inst, "members", ())):
            return name, f"{instance}.{var}"
    return instance, var


class _DiscreteOutput:
    """A variable that is not Real, read from the FMU when sampled through
    the fmi2Get*/fmi3Get* of its type: integers, Enumeration, Float32 and
    Boolean as numbers, String and Binary (hexadecimal digits) as text."""

    def __init__(self, inst, var: str):
        self.inst, self.var = inst, var
        self.kind = inst.variables[var].type

    def __getitem__(self, _):
        value = self.inst.get_values([self.var])[0]
        return value if self.kind in TEXT_TYPES else float(value)


# Values (rows x columns) a streaming recorder holds before it hands them on: 8192 keep the
# chunk's floats and CSV text near 1 MB (65,536 took 13 MB, a quarter of a short run's whole
# peak; benchmarks/bench_memory.py), and the compiled core's 4096-row buffer drains in between.
CHUNK_VALUES = 1 << 13


class Recorder:
    def __init__(self, master, outputs: list[tuple[str, str]], interval: float | None = None,
                 ticks_of: str | None = None, times: bool = False,
                 limit: int | None = None, sink=None):
        """`limit`: the values (rows x columns, time included) it may keep;
        a run that would keep more (rows at events off the grid, which no
        check before the run can count) fails with SimulationError. `sink`:
        where the rows go as the run goes (see the module); no limit then."""
        self.master = master
        # An FMI 3.0 array is recorded element by element ("y[0]", "A[1,2]").
        outputs = [_in_group(master.instances, i, v) for i, v in outputs]
        self.outputs = [(i, x) for i, v in outputs for x in master.instances[i].elements.get(v, [v])]
        # A Model Exchange group's variables are already "member.variable" (engine/me_group.py).
        self.names = [v if getattr(master.instances[i], "qualified_names", False) else f"{i}.{v}"
                      for i, v in self.outputs]
        self.times = times  # the time column even with no outputs
        self._rows = bool(self.outputs) or times
        self.columns: dict[str, list[float]] = {"time": [], **{n: [] for n in self.names}}
        self.ticks: list[float] = []
        self._sources = []
        # Positions by name, once (list.index per output made 100,000 outputs quadratic).
        discrete = {i: set(names) for i, names in master.discrete_outputs.items()}
        out_pos = master.ports.out_pos
        for i, v in self.outputs:
            if v in discrete.get(i, ()):
                self._sources.append((_DiscreteOutput(master.instances[i], v), 0))
            else:
                self._sources.append((master.ports[i].out, out_pos[i][v]))
        self._tick_port = master.ports[ticks_of] if ticks_of else None
        self._tick_pos = self._tick_port.out_names.index("tick_time") if ticks_of else 0
        self._last_tick = self._tick_port.out[self._tick_pos] if self._tick_port else 0.0
        self._interval = interval
        self._stride = max(1, round(interval / master.settings.step)) if interval else 1
        self._k = 0  # grid points seen
        self.sink = sink
        self.limit = None if sink is not None else limit
        # rows x columns (time included) > limit  <=>  rows > limit // columns
        self._max_rows = self.limit // (len(self.names) + 1) if self.limit is not None else None
        self._chunk_rows = max(1, CHUNK_VALUES // (len(self.names) + 1))
        self._handed = 0  # rows handed to the sink
        self._last_t: float | None = None  # the last row's time

    def stream_to(self, sink) -> None:
        """Hand the rows to `sink` from now on (see the module): no `limit` then."""
        self.sink = sink
        self.limit = self._max_rows = None

    @property
    def text_names(self) -> set[str]:
        """The columns recorded as text (String and Binary variables)."""
        return {n for n, (src, _) in zip(self.names, self._sources)
                if isinstance(src, _DiscreteOutput) and src.kind in TEXT_TYPES}

    @property
    def rows(self) -> int:
        """Rows recorded so far (handed on or kept)."""
        return self._handed + len(self.columns["time"])

    def _flush(self) -> None:
        """Hand the rows kept to the sink; the lists are emptied in place (the
        compiled engine appends to these very lists)."""
        cols = self.columns
        if not cols["time"]:
            return
        self._last_t = cols["time"][-1]
        self._handed += len(cols["time"])
        self.sink.write([cols["time"]] + [cols[n] for n in self.names])
        for c in cols.values():
            del c[:]

    def series(self):
        """The recorded series: the sink's (every row handed on, its files
        closed) or the columns kept."""
        if self.sink is None:
            return self.columns
        self._flush()
        sink, self.sink = self.sink, None
        self._series = sink.close()
        return self._series

    def abort(self) -> None:
        """A run that ends without a result or a history: the sink's files go."""
        if self.sink is not None:
            sink, self.sink = self.sink, None
            sink.abort()

    def _last_time(self) -> float | None:
        return self.columns["time"][-1] if self.columns["time"] else self._last_t

    def start(self) -> None:
        """Record the first row, at the master's current point."""
        if self._rows:
            self._row(self.master.t)

    def finish(self) -> None:
        """Record the run's end when the interval left it out (a stop off
        the recording grid): fmpy's result always ends at its stop."""
        last = self._last_time()
        if self._rows and (last is None or last < self.master.t):
            self._row(self.master.t)

    def _row(self, t: float) -> None:
        if self._max_rows is not None and len(self.columns["time"]) >= self._max_rows:
            raise self.over(t)
        self.columns["time"].append(t)
        for name, (arr, j) in zip(self.names, self._sources):
            self.columns[name].append(arr[j])
        if self.sink is not None and len(self.columns["time"]) >= self._chunk_rows:
            self._flush()

    def over(self, t: float) -> SimulationError:
        """The error of a run that would keep more than `limit` values."""
        rows = len(self.columns["time"])
        e = SimulationError(
            f"the run would keep more than {self.limit:.3g} recorded values in memory ({rows} rows of "
            f"{len(self.names) + 1} columns; rows at events off the record grid count too): give a "
            "record.interval, a shorter span (experiment.stop) or fewer record.outputs", time=t)
        e.last_point = self.columns["time"][-1] if rows else None
        return e

    def check_limit(self, t: float) -> None:
        """After rows were added in bulk (the compiled core): raise when past
        `limit`; with a sink, hand a full chunk on."""
        if self._max_rows is not None and len(self.columns["time"]) > self._max_rows:
            raise self.over(t)
        if self.sink is not None and len(self.columns["time"]) >= self._chunk_rows:
            self._flush()

    def __call__(self, master) -> None:
        if self._tick_port is not None:
            tt = self._tick_port.out[self._tick_pos]
            if tt != self._last_tick and tt > 0:
                self.ticks.append(tt)
                self._last_tick = tt
        if not self._rows:
            return
        k = (master.t - master.start_time) / master.settings.step
        if abs(k - round(k)) < 1e-6:  # on the grid (events add points off it)
            self._k += 1
            if self._k % self._stride:
                return
        elif self._interval:
            return
        self._row(master.t)
