"""The compiled stepping core: the master's loop in C, the same bits.

``CompiledMaster`` is a ``Master`` whose ``step`` and ``run_until`` run in
src_c/master/ (cw_step.c and its files by job), a line-for-line twin of master.py with
coupling.py, location.py, checkpoints.py and recording.py. It calls each
FMU's fmi2 functions through the pointers of the library fmpy loaded, so
it steps any FMI 2.0 Co-Simulation FMU, and FMI 1.0 and 3.0 ones through
the core's adapters (cw1_*, cw3_*) with the same fmi2 shape. Loading, initialization, the
wiring and everything a scene or an analysis asks for stay in Python: the
core gets the ports' preallocated arrays and runs as many steps as it can
before Python is needed again (the stop time, a full recording buffer, an
output to name for diverging). Components at their own steps (``rates``,
engine/multirate.py) step in cw_rates.c by the same rule.

``make_master`` chooses: ``master.engine = "python"`` is the reference
loop, ``"compiled"`` the core (bad input when it cannot serve the
settings), ``"auto"`` the core where it can, else Python. The core does
not do step doubling (``master.richardson``).
"""

from __future__ import annotations

import ctypes
import itertools
import math
import threading
import weakref
from array import array
from ctypes import POINTER, Structure, byref, c_double, c_int, c_longlong, c_uint, c_void_p

from ..errors import SceneError, SimulationError
from ..paths import core_library
from ..fmi import layout
from . import cvode
from ..fmi.contract import CORE_CALLS, Instance
from ..fmi.cs1 import _Fmi1
from ..fmi.cs3 import _Events
from .clocks import ClockedMaster, clock_tables, clocks_text
from .compiled_clocks import CLOCK_EVENT, CoreClocks, _Clocks
from .master import Master
from .multirate import REFUSALS, is_multirate, slow_ones
from .parallel import group_ends
from .model_exchange import _ME
from .ports import link_type
from .recording import Recorder, _DiscreteOutput
from .samples import Samples
from .settings import MasterSettings, Statistics, with_model_exchange
from .wiring import Link

HISTORY = 3  # input history for divided differences (HISTORY in cw_structs.h)
ROWS_PER_CALL = 4096  # recording buffer, rows
MAX_SINCE = 256  # steps kept since a checkpoint (the master forces one after 64)

_DONE, _BUFFER_FULL, _CHECK_DIVERGENCE, _WATCHED, _ENDED, _SLICE_OVER, _CLOCK_EVENT = 0, 1, 2, 3, 4, 5, CLOCK_EVENT
_ERR_FMI, _ERR_NO_CHECKPOINT, _ERR_REPLAY, _ERR_LOCATE, _ERR_CAPACITY, _ERR_LOOP = -1, -2, -3, -4, -5, -6
_ERR_RATES = -7  # a step across rates refused: err_call is the position in multirate.REFUSALS
# What the core's err_call names: the contract's call (instance.named) and what it was for.
_CALLS = [("doStep", ""), ("getReal", ""), ("setReal", " of inputs"), ("setInputDerivatives", ""),
          ("getState", ""), ("setState", "")]


def _fields(pointers: list[str], doubles: list[str], longs: list[str], ints: list[str]):
    return ([(n, c_void_p) for n in pointers] + [(n, c_double) for n in doubles]
            + [(n, c_longlong) for n in longs] + [(n, c_int) for n in ints])


class _Strict(Structure):
    """A struct that refuses a field name it does not have (ctypes would
    silently add a Python attribute, and C would never see the value)."""

    def __setattr__(self, name, value):
        if not name.startswith("_") and name not in self._names:
            raise AttributeError(f"{type(self).__name__} has no field {name}")
        super().__setattr__(name, value)


class _Port(_Strict):
    _fields_ = _fields(
        ["comp", "doStep", "getReal", "setReal", "setInputDerivatives", "getOutputDerivatives",
         "getState", "setState", "state", "out_vr", "out", "in_vr", "inp", "der_vr", "der_order",
         "der", "src_port", "src_pos", "sent", "dsrc_port", "dsrc_vr", "dsrc_m", "hist_t",
         "hist_v", "snap_hist_t", "snap_hist_v", "scaled", "in_factor", "in_offset"],
        ["out_time", "lowered_at"], [],
        ["n_out", "n_in", "n_z", "max_output_derivative_order", "sent_valid", "hist_n",
         "snap_hist_n", "n_scaled", "ext_order", "pad_"]
    ) + _fields(["it_start", "it_end"], [], [], ["can_interpolate",  # strong coupling
                                                  "rate"]) \
      + _fields(["add_at", "add_port", "add_pos"], [], [], ["n_adds", "pad3_"])  # rate: its decimation factor (_Rates); sums (Port.adds)


class _Master(_Strict):
    _fields_ = _fields(
        ["ports", "first", "dynamic", "first_in_order", "final_order", "buffer", "z_port", "z_pos",
         "z_start", "z_end", "zs_port", "zs_pos", "zs_vr", "prev_kind", "prev_u", "prev_du",
         "amp_u", "amp_du", "z_seen", "end_rate_set", "end_rate", "snap_z_end", "since"],
        ["t", "start_time", "step", "event_time_tolerance", "event_indicator_tolerance",
         "divergence_limit", "time_to_zero", "step_cap", "located_from", "snap_t",
         "snap_time_to_zero", "err_t", "err_h"],
        ["steps", "events", "event_iterations", "rollbacks", "replays", "states_saved"],
        ["n_ports", "n_first", "n_dynamic", "n_first_in_order", "n_final", "n_buffer", "n_z",
         "cap_since", "jacobi", "extrapolation", "locating", "has_sources", "after_event",
         "after_event_step", "sample_countdown", "prev_valid", "stale_sources", "snap_valid",
         "snap_after_event", "n_since", "max_replay_steps", "diverged", "err_port", "err_call", "err_status",
         "orders_lowered"]
    ) + [("n_fmi3", c_int), ("pad4_", c_int), ("fmi3", c_void_p)] + _fields(  # FMI 3.0 adapters (fmu3._Events), whose time events cap the step
        ["pred_kind", "pred_u", "pred_du", "pred_ddu", "last_z"],  # prediction (EventLocator.sample, .plan)
        ["sampled_t", "sampled_before_t", "last_t"], ["predicted_landings", "mispredicted"],
        ["predicting", "last_valid"]
    ) + _fields([], ["iteration_tolerance"], ["coupling_iterations"], ["iterations", "pad3_"]) + [  # strong coupling
        ("loops", c_void_p),  # _Loops: the algebraic loops solved in the orders
        ("pool", c_void_p), ("par_end", c_void_p), ("par_status", c_void_p),  # master.threads (engine/parallel.py)
        ("after_start", c_void_p), ("after_order", c_void_p),  # per dynamic instance, the updates after its step
        ("inputs", c_void_p),  # a _Inputs: inputs driven from samples, or NULL
        ("clocks", c_void_p),  # a compiled_clocks._Clocks: FMI 3.0 clocks, or NULL
        ("rates", c_void_p)]  # a _Rates: components at their own steps, or NULL


class _Marks(_Strict):
    """A run to marks (engine/marks.py) and its place."""

    _fields_ = _fields(["times", "sets", "values", "in_port", "in_vr", "out_port", "out_pos", "prev_port",
                        "prev_pos", "previous", "watch_port", "watch_pos", "seen", "rows"],
                       ["margin", "max_step", "tolerance", "period", "last_event", "prev_event"], [],
                       ["n_times", "next", "n_in", "n_out", "n_prev", "n_watch", "capacity", "n_rows", "follow",
                        "has_prev", "record", "stop_at_change", "stopped", "pad_"])


class _Loop(_Strict):
    _fields_ = _fields(
        ["members", "u_port", "u_pos", "u_src", "u_src_pos", "u_factor", "u_offset", "u_scaled", "r"],
        ["fail_worst"], [],
        ["n_members", "n", "fail_why", "fail_at", "fail_sweeps", "fail_newton"])


class _Loops(_Strict):
    _fields_ = _fields(["loop"], ["tolerance"], ["iterations", "fallbacks"], ["n_loops", "pad_"])


class _Inputs(_Strict):
    """The sample table and the Real inputs it drives (engine/samples.py)."""

    _fields_ = _fields(["times", "values", "continuous", "events", "port_start", "vr", "signal", "value",
                        "after_step"],
                       [], [], ["n_times", "n_signals", "n_events", "pad_"])


class _Rates(_Strict):
    """Components at their own steps (engine/multirate.py, cw_rates.c): per
    link across rates, its held copy (a port past the real ones) and its source."""

    _fields_ = _fields(["held_port", "held_pos", "src_port", "src_pos", "every", "starts"], [], ["count"],
                       ["n_links", "pad_"])


class _Recorder(_Strict):
    _fields_ = _fields(
        ["col_port", "col_pos", "rows", "ticks"], ["last_tick"], ["grid_seen", "grid_k"],
        ["n_cols", "capacity", "n_rows", "tick_capacity", "n_ticks", "stride", "tick_port",
         "tick_pos", "has_interval", "pad_"])


for _struct in (_Port, _Master, _Recorder, _Marks, _Loop, _Loops, _Inputs, _Rates):
    _struct._names = frozenset(n for n, _ in _struct._fields_)

_lib = None
_lib_error: str | None = None
_lib_lock = threading.Lock()


def load_core():
    """The core library (ctypes), or None with the reason in ``core_problem()``."""
    global _lib, _lib_error
    with _lib_lock:
        if _lib is None and _lib_error is None:
            path = core_library()
            try:
                lib = ctypes.CDLL(str(path))
            except OSError as e:
                _lib_error = f"the compiled core {path} cannot be loaded ({e}); build it with tools/setup.sh"
                return None
            from .me_group import _Group  # with the core, not with the engine (engine/system.py)
            for lookup, name, struct in (
                    ("cw_layout", "port", _Port), ("cw_layout", "master", _Master),
                    ("cw_layout", "recorder", _Recorder), ("cw_layout", "fmi3", _Events),
                    ("cw_layout", "marks", _Marks), ("cw_layout", "fmi1", _Fmi1), ("cw_layout", "loop", _Loop),
                    ("cw_layout", "loops", _Loops), ("cw_layout", "inputs", _Inputs),
                    ("cw_layout", "clocks", _Clocks), ("cw_layout", "rates", _Rates),
                    ("cwme_layout", "me", _ME), ("cwme_layout", "sundials", cvode.Table),
                    ("cwme_layout", "me_group", _Group)):
                differs = layout.problem(lib, lookup, name, struct)
                if differs:
                    _lib_error = (f"{path} was built from another version of the core ({differs}); "
                                  "rebuild it with tools/setup.sh")
                    return None
            lib.cw_step.argtypes = [POINTER(_Master), c_double, POINTER(c_double)]
            lib.cw_step.restype = c_int
            lib.cw_run_until.argtypes = [POINTER(_Master), c_double, POINTER(_Recorder), c_double]
            lib.cw_run_until.restype = c_int
            lib.cw_start.argtypes = [POINTER(_Master)]
            lib.cw_start.restype = None
            lib.cw_run_marks.argtypes = [POINTER(_Master), c_double, POINTER(_Marks), c_double]
            lib.cw_run_marks.restype = c_int
            lib.cw_discontinuity.argtypes = [POINTER(_Master)]
            lib.cw_discontinuity.restype = None
            lib.cw_pool_new.argtypes = [c_int]
            lib.cw_pool_new.restype = c_void_p
            lib.cw_pool_free.argtypes = [c_void_p]
            lib.cw_pool_free.restype = None
            lib.cw_record_point.argtypes = [POINTER(_Master), POINTER(_Recorder)]
            lib.cw_record_point.restype = None
            _lib = lib
        return _lib


def core_problem() -> str | None:
    load_core()
    return _lib_error


def unsupported(settings: MasterSettings) -> str | None:
    """Why the core cannot run these settings, or None."""
    if settings.richardson:
        return "the compiled core does not do step doubling (master.richardson = true)"
    return None


MAX_RATE = 2 ** 31 - 1  # the core's decimation factors are C ints (cw_port.rate)


def unsupported_rates(settings: MasterSettings, rates: dict[str, int] | None,
                      indicators: dict[str, object]) -> str | None:
    """Why the core cannot step these components at their own steps, or
    None. The core (cw_rates.c) steps what engine/multirate.py steps: whole
    base steps, inputs held over each component's own step, no rollback.
    What the Python engine may do across rates beyond that (event location,
    input polynomials, strong coupling) is named here, so that "auto" gives
    it to Python. `indicators`: per instance, its event indicators."""
    if not is_multirate(rates):
        return None
    big = [f"{n} every {k}" for n, k in rates.items() if k > MAX_RATE]
    if big:
        return (f"the compiled core counts at most {MAX_RATE} base steps to a component's step, and "
                f"{', '.join(big)} base steps here")
    across = f"across rates ({slow_ones(rates)} base steps)"
    if settings.extrapolation:
        return f"the compiled core holds inputs over a step {across}: master.extrapolation = {settings.extrapolation}"
    if settings.iterations > 0:
        return f"the compiled core does not repeat steps {across}: master.iterations = {settings.iterations}"
    if settings.event_location and any(indicators.values()):
        return f"the compiled core does not locate events {across}: master.event_location = true"
    return None


def unsupported_links(types) -> str | None:
    """Why the core cannot pass these links on, or None. `types`: (link
    text, FMI type) pairs; the core passes Real values only."""
    for text, kind in types:
        if kind != "Real":
            return f"the compiled core passes Real connections only ({text} is {kind})"
    return None


def unsupported_inputs(types) -> str | None:
    """Why the core cannot set these sampled inputs, or None. `types`:
    ("instance.variable", FMI type) pairs; the core sets Real inputs only."""
    for name, kind in types:
        if kind != "Real":
            return f"the compiled core sets sampled Real inputs only ({name} is {kind})"
    return None


def make_master(instances: dict[str, Instance], links: list[Link], settings: MasterSettings,
                start_time: float = 0.0, step_order: list[str] | None = None,
                extra_outputs: dict[str, list[str]] | None = None, inputs: Samples | None = None,
                rates: dict[str, int] | None = None) -> Master:
    """The master that ``settings.engine`` asks for (see the module's docstring).
    `rates`: {instance: decimation factor} where components step at their
    own multiples of settings.step (engine/multirate.py)."""
    settings.check()
    clocks = clocks_text(instances)
    if clocks is not None and is_multirate(rates):
        raise SceneError(f"rates: a clock ticks every component at master.step, and {slow_ones(rates)} base steps "
                         f"here; a scene with {clocks} steps every component at master.step")
    reason = None
    if settings.engine != "python":
        # Clock connections, clocked links and clock columns are ClockedMaster's (engine/clocks.py), not the core's.
        tables = clock_tables(instances)

        def plain(inst: str, var: str) -> bool:
            t = tables.get(inst)
            return t is None or (var not in t.clocks and var not in t.clocked)

        types = [(f"{k.src}.{k.output} -> {k.dst}.{k.input}", link_type(instances, k)) for k in links
                 if plain(k.src, k.output) and plain(k.dst, k.input)]
        sampled = [] if inputs is None else [
            (s.name, instances[s.instance].variables[s.variable].type) for s in inputs.signals
            if s.instance in instances and s.variable in instances[s.instance].variables
            and plain(s.instance, s.variable)]
        refused = next((r for r in (getattr(i, "compiled_reason", None) for i in instances.values()) if r), None)
        indicators = {n: getattr(i, "event_indicators", ()) for n, i in instances.items()}
        reason = (unsupported(settings) or unsupported_rates(settings, rates, indicators) or refused
                  or unsupported_links(types) or unsupported_inputs(sampled) or core_problem())
        if reason is None:
            if clocks is not None:
                return CompiledClockedMaster(instances, links, settings, start_time, step_order, extra_outputs, inputs)
            return CompiledMaster(instances, links, settings, start_time, step_order, extra_outputs, inputs, rates)
        if settings.engine == "compiled":
            raise SceneError(f"master.engine = 'compiled': {reason} (use 'auto' or 'python')")
    if clocks is not None:  # FMI 3.0 clocks on the Python engine (engine/clocks.py)
        master = ClockedMaster(instances, links, settings, start_time, step_order, extra_outputs, inputs)
    else:
        master = Master(instances, links, settings, start_time, step_order, extra_outputs, inputs, rates)
    master.engine_reason = reason
    return master


# The statistics the core counts (`rejected` stays 0: the core does not
# do step doubling).
_CORE_STATS = ("steps", "events", "event_iterations", "rollbacks", "replays", "states_saved",
               "predicted_landings", "mispredicted", "coupling_iterations")



_TYPECODES = {c_double: "d", c_int: "i", c_uint: "I"}  # array's codes of the same C types


def _array(ctype, values, n: int | None = None):
    values = list(values)
    size = max(1, n if n is not None else len(values))
    code = _TYPECODES.get(ctype)
    if code is None or len(values) != size:
        return (ctype * size)(*values)
    # array converts in one C loop and the bytes are copied: ctypes' own
    # constructor sets the items one by one (a run to marks: 3 per period).
    try:
        return (ctype * size).from_buffer_copy(array(code, values))
    except (OverflowError, TypeError):  # ctypes' own conversions (it wraps integers)
        return (ctype * size)(*values)


class CompiledMaster(Master):
    """``Master`` with ``step`` and ``run_until`` in the compiled core."""

    engine = "compiled"
    # Wall time of one core call, s: a long run returns to Python this often
    # and is called again where it stopped (Python runs signal handlers only
    # between calls). 0 returns every 16 steps (the tests compare the bits).
    slice_s = 0.05

    def __init__(self, instances, links, settings, start_time=0.0, step_order=None, extra_outputs=None,
                 inputs=None, rates=None):
        self._lib = load_core()
        super().__init__(instances, links, settings, start_time, step_order, extra_outputs, inputs, rates)
        self.__dict__.pop("step", None)  # across rates too, the core steps (cw_rates.c), not MultiRate.step
        self._build()

    # The master's state lives in the C struct; before it exists (inside
    # Master.__init__) these go to the instance dict.
    @property
    def t(self) -> float:
        core = self.__dict__.get("_core")
        return self.__dict__["_t_before_core"] if core is None else core.t

    @t.setter
    def t(self, value: float) -> None:
        core = self.__dict__.get("_core")
        if core is None:
            self.__dict__["_t_before_core"] = value
        else:
            core.t = value

    @property
    def MAX_REPLAY_STEPS(self) -> int:  # noqa: N802 (Master's class constant, per instance here)
        return self._core.max_replay_steps

    @MAX_REPLAY_STEPS.setter
    def MAX_REPLAY_STEPS(self, value: int) -> None:  # noqa: N802
        self._core.max_replay_steps = value

    @property
    def stats(self) -> Statistics:
        c, lc = self._core, self._loops
        return with_model_exchange(
            Statistics(**{name: getattr(c, name) for name in _CORE_STATS},
                       loop_iterations=lc.iterations, loop_fallbacks=lc.fallbacks),
            self._own_counts)

    @stats.setter
    def stats(self, value: Statistics) -> None:
        core = self.__dict__.get("_core")
        if core is not None:
            for name in _CORE_STATS:
                setattr(core, name, getattr(value, name))
            self._loops.iterations, self._loops.fallbacks = value.loop_iterations, value.loop_fallbacks

    def count_loop(self, iterations: int, fallbacks: int) -> None:
        self._loops.iterations += iterations
        self._loops.fallbacks += fallbacks

    def _build(self) -> None:
        """Hand the ports' arrays to a C master struct (kept alive here)."""
        keep = self._keep = []

        def ref(obj) -> int:
            keep.append(obj)
            return ctypes.addressof(obj)

        ports = self.ports
        index = {id(p): i for i, p in enumerate(ports.all)}
        held = self._held_copies(index)
        cports = (_Port * (len(ports.all) + len(held)))()
        for i, p in enumerate(ports.all):
            inst, c = p.inst, cports[i]
            # The functions the core's port calls and their first argument,
            # as the instance's face gives them (contract.core_calls).
            c.comp, calls = inst.core_calls(self._lib)
            for field, address in zip(CORE_CALLS, calls, strict=True):
                setattr(c, field, address)
            c.state = ctypes.addressof(inst._state)
            c.out_vr, c.out = ref(p.out_vr), ctypes.addressof(p.out)
            c.in_vr, c.inp = ref(p.in_vr), ref(p.inp)
            c.der_vr, c.der_order, c.der = ref(p.der_vr), ref(p.der_order), ref(p.der)
            if any(k != pos for pos, (k, _, _) in enumerate(p.sources)):
                raise SimulationError(f"{inst.name}: an input is connected twice")
            def feed(src, i=i):  # the port an input reads: across rates, its held copy of src
                return held.get((i, index[id(src)]), index[id(src)])

            c.src_port = ref(_array(c_int, (feed(src) for _, src, _ in p.sources)))
            c.src_pos = ref(_array(c_int, (j for _, _, j in p.sources)))
            c.sent = ref(_array(c_double, [], p.n_in))
            for name in ("hist_t", "snap_hist_t"):
                setattr(c, name, ref(_array(c_double, [], HISTORY + 1)))
            for name in ("hist_v", "snap_hist_v"):
                setattr(c, name, ref(_array(c_double, [], (HISTORY + 1) * p.n_in)))
            c.scaled = ref(_array(c_int, (k for k, _, _ in p.scale)))
            c.in_factor = ref(_array(c_double, (f for _, f, _ in p.scale)))
            c.in_offset = ref(_array(c_double, (o for _, _, o in p.scale)))
            c.n_scaled = len(p.scale)
            c.add_at = ref(_array(c_int, (k for k, _, _ in p.adds)))
            c.add_port = ref(_array(c_int, (feed(src) for _, src, _ in p.adds)))
            c.add_pos = ref(_array(c_int, (j for _, _, j in p.adds)))
            c.n_adds = len(p.adds)
            c.it_start, c.it_end = ref(_array(c_double, [], p.n_in)), ref(_array(c_double, [], p.n_in))
            c.can_interpolate = int(bool(inst.can_interpolate_inputs))
            c.ext_order = p.ext_order
            c.n_out, c.n_in, c.n_z = p.n_out, p.n_in, len(p.z_pos)
            c.max_output_derivative_order = inst.max_output_derivative_order
        self._cports = cports
        rates = self._build_rates(cports, held, index, ref)
        loc = self.locator
        z_port, z_pos = [], []
        for p in loc.ports:
            z_port += [index[id(p)]] * len(p.z_pos)
            z_pos += p.z_pos
        zs = [(index[id(info[0])], info[1], info[3][0]) if info is not None else (-1, 0, 0)
              for info in loc.sources]
        nz = len(z_port)
        m = self._core = _Master()
        m.ports = ctypes.addressof(cports)
        # An order's loop is -(its index + 1).
        index.update({id(loop): -(i + 1) for i, loop in enumerate(ports.loops)})
        for name, count, order in (("first", "n_first", ports.first), ("dynamic", "n_dynamic", ports.dynamic),
                                   ("first_in_order", "n_first_in_order", ports.first_in_order),
                                   ("final_order", "n_final", ports.final_order)):
            setattr(m, name, ref(_array(c_int, (index[id(p)] for p in order))))
            setattr(m, count, len(order))
        m.loops = ctypes.addressof(self._build_loops(index, ref))
        after = self._updates_after
        m.after_start = ref(_array(c_int, itertools.accumulate((len(x) for x in after), initial=0)))
        m.after_order = ref(_array(c_int, (index[id(x)] for xs in after for x in xs)))
        m.buffer, m.n_buffer = ctypes.addressof(ports.buffer), len(ports.buffer)
        m.z_port, m.z_pos = ref(_array(c_int, z_port)), ref(_array(c_int, z_pos))
        m.zs_port, m.zs_pos = ref(_array(c_int, (a for a, _, _ in zs))), ref(_array(c_int, (b for _, b, _ in zs)))
        m.zs_vr = ref(_array(c_uint, (v for _, _, v in zs)))
        for name in ("z_start", "z_end", "prev_u", "prev_du", "amp_u", "amp_du", "z_seen", "end_rate",
                     "snap_z_end"):
            setattr(m, name, ref(_array(c_double, [], nz)))
        m.prev_kind, m.end_rate_set = ref(_array(c_int, [], nz)), ref(_array(c_int, [], nz))
        m.pred_kind = ref(_array(c_int, [], 2 * nz))
        for name in ("pred_u", "pred_du", "pred_ddu"):
            setattr(m, name, ref(_array(c_double, [], 2 * nz)))
        m.last_z = ref(_array(c_double, [], nz))
        m.predicting = int(self._predicting)
        m.iterations, m.iteration_tolerance = int(self.settings.iterations), self.settings.iteration_tolerance
        m.since, m.cap_since = ref(_array(c_double, [], MAX_SINCE)), MAX_SINCE
        m.n_ports, m.n_z = len(ports.all), nz
        fmi3 = [ctypes.addressof(ev) for ev in self.time_events]
        m.fmi3, m.n_fmi3 = ref(_array(c_void_p, fmi3)), len(fmi3)
        s = self.settings
        m.t = self.__dict__.pop("_t_before_core", self.start_time)
        m.start_time, m.step = self.start_time, s.step
        m.event_time_tolerance, m.event_indicator_tolerance = s.event_time_tolerance, s.event_indicator_tolerance
        m.divergence_limit = s.divergence_limit
        m.jacobi, m.extrapolation = int(self._jacobi), int(s.extrapolation)
        m.locating, m.has_sources = int(self._locating), int(loc.has_sources)
        m.after_event = 1
        m.max_replay_steps = Master.MAX_REPLAY_STEPS
        self._start_threads(m, ref)
        if self.file_inputs is not None:
            m.inputs = self._inputs()
        if rates is not None:
            m.rates = ctypes.addressof(rates)
        self._core_ptr = byref(m)
        self._taken = c_double()
        self._taken_ptr = byref(self._taken)
        self._empty_recorder = _Recorder(grid_k=-1, tick_port=-1, capacity=1, tick_capacity=1, stride=1)

    def _held_copies(self, index: dict) -> dict[tuple[int, int], int]:
        """Across rates, {(target port, source port): its held copy's port},
        a port past the real ones per pair whose factors differ (as
        MultiRate.attach routes each such link, a sum's terms too, through a
        held copy)."""
        mr = self._multirate
        if mr is None:
            return {}
        held = {}
        for p in self.ports.all:
            for _, src, _ in p.sources + p.adds:  # adds: a sum's further terms
                key = (index[id(p)], index[id(src)])
                if mr.k[src.inst.name] != mr.k[p.inst.name] and key not in held:
                    held[key] = len(self.ports.all) + len(held)
        return held

    def _build_rates(self, cports, held: dict, index: dict, ref) -> _Rates | None:
        """The core's factors, held copies and links across rates, or None
        where every component steps at the base step."""
        mr = self._multirate
        if mr is None:
            return None
        ports = self.ports.all
        for p, c in zip(ports, cports):
            c.rate = mr.k[p.inst.name]
        for (_, s), h in held.items():
            c, src = cports[h], ports[s]
            c.out, c.n_out = ref(_array(c_double, [], src.n_out)), src.n_out
        links = [(held[(i, index[id(src)])], j, index[id(src)], j, math.lcm(mr.k[src.inst.name], mr.k[p.inst.name]))
                 for i, p in enumerate(ports) for _, src, j in p.sources + p.adds if (i, index[id(src)]) in held]
        column = list(zip(*links)) or [(), (), (), (), ()]
        r = _Rates(held_port=ref(_array(c_int, column[0])), held_pos=ref(_array(c_int, column[1])),
                   src_port=ref(_array(c_int, column[2])), src_pos=ref(_array(c_int, column[3])),
                   every=ref(_array(c_longlong, column[4])), starts=ref(_array(c_double, [], len(ports))),
                   n_links=len(links))
        self._keep.append(r)
        return r

    def _start_threads(self, m: _Master, ref) -> None:
        """master.threads > 1: the core's thread pool, and which dynamic
        instances step at once (engine/parallel.py)."""
        threads = self.settings.threads
        if threads < 2:
            return
        if self._multirate is not None:
            self.coupling.note(f"master.threads = {threads}: across rates the compiled core steps one instance "
                               "at a time (cw_rates.c)")
            return
        pool = self._lib.cw_pool_new(threads)
        if not pool:
            self.coupling.note(f"master.threads = {threads}: the system refused to start the threads; "
                               "stepping on one")
            return
        self._pool_free = weakref.finalize(self, self._lib.cw_pool_free, pool)  # at the latest with the master
        m.pool = pool
        if self.file_inputs is None:
            ends = group_ends(self.ports, self._jacobi)
        else:  # sampled inputs are set between an instance's step and its outputs' read: one at a time
            ends = [a + 1 for a in range(len(self.ports.dynamic))]
        m.par_end = ref(_array(c_int, ends))
        m.par_status = ref(_array(c_int, [], 2 * len(self.ports.all)))

    def stop_threads(self) -> None:
        """Stop the core's threads (System.free calls it); the master steps on one from then on."""
        stop = self.__dict__.get("_pool_free")
        if stop is not None:
            self._core.pool = None
            stop()
    def _inputs(self) -> int:
        """The core's table of sampled inputs (Real ones: make_master chose
        Python for the others), as a _Inputs struct's address."""
        fi = self.file_inputs
        samples = fi.samples
        n = len(samples.times)
        values = array("d")
        for s in samples.signals:
            values.extend(float(x) for x in s.values)
        starts, vrs, signals = [], [], []
        for p in self.ports.all:
            starts.append(len(vrs))
            cols, vr, _ = fi.real.get(p.inst.name, ([], [], None))
            vrs += list(vr)
            signals += cols
        starts.append(len(vrs))
        ref = self._ref
        c = _Inputs(times=ref(_array(c_double, samples.times)), values=ref(_array(c_double, values)),
                    continuous=ref(_array(c_int, (int(s.continuous) for s in samples.signals))),
                    events=ref(_array(c_double, samples.events)), port_start=ref(_array(c_int, starts)),
                    vr=ref(_array(c_uint, vrs)), signal=ref(_array(c_int, signals)),
                    value=ref(_array(c_double, [], len(vrs))),
                    after_step=ref(_array(c_int, (int(getattr(p.inst, "outputs_after_inputs", True))
                                                  for p in self.ports.all))),
                    n_times=n, n_signals=len(samples.signals), n_events=len(samples.events))
        return ref(c)

    def _build_loops(self, index: dict, ref) -> _Loops:
        """The algebraic loops for the core (those broken by a delay are never in its orders)."""
        loops = self.ports.loops
        cl = (_Loop * max(1, len(loops)))()
        for c, loop in zip(cl, loops):
            n = loop.n
            u = loop.unknowns
            c.members = ref(_array(c_int, (index[id(p)] for p in loop.members)))
            c.u_port = ref(_array(c_int, (index[id(p)] for p, *_ in u)))
            c.u_pos = ref(_array(c_int, (k for _, k, *_ in u)))
            c.u_src = ref(_array(c_int, (index[id(src)] for _, _, src, *_ in u)))
            c.u_src_pos = ref(_array(c_int, (x[3] for x in u)))
            c.u_factor = ref(_array(c_double, (x[4] for x in u)))
            c.u_offset = ref(_array(c_double, (x[5] for x in u)))
            c.u_scaled = ref(_array(c_int, (int(x[6]) for x in u)))
            c.r = ref(_array(c_double, [], n))  # Newton's work the core takes when it needs it
            c.n_members, c.n = len(loop.members), n
        self._keep.append(cl)
        lc = self._loops = _Loops(loop=ctypes.addressof(cl), tolerance=self.settings.iteration_tolerance,
                                  n_loops=len(loops))
        return lc

    # -- the soft state, in C --------------------------------------------------

    def _start(self) -> None:
        # The derivative sources are known only now (after initialization).
        by_inst = {id(p.inst): i for i, p in enumerate(self.ports.all)}
        found = self.coupling.derivative_sources
        for i, p in enumerate(self.ports.all):
            c = self._cports[i]
            dport, dvr, dm = [], [], []
            for k in range(p.n_in):
                d = found.get((p.inst.name, k))
                dport.append(by_inst[id(d[0])] if d is not None else -1)
                dvr += [d[1][0], d[1][1]] if d is not None else [0, 0]
                dm.append(d[4] if d is not None else 0)
            c.dsrc_port = self._ref(_array(c_int, dport))
            c.dsrc_vr = self._ref(_array(c_uint, dvr))
            c.dsrc_m = self._ref(_array(c_int, dm))
            c.out_time = p.out_time
            c.sent_valid = 0
        self._lib.cw_start(self._core_ptr)

    def _ref(self, obj) -> int:
        self._keep.append(obj)
        return ctypes.addressof(obj)

    def discontinuity(self) -> None:
        self._lib.cw_discontinuity(self._core_ptr)

    def record_history(self) -> None:
        # Only Master.__init__ calls this here, before the core exists;
        # cw_start and the core keep the history from then on.
        if self.__dict__.get("_core") is None:
            super().record_history()

    # -- stepping ----------------------------------------------------------------

    def _orders_lowered(self) -> None:
        """Say what the core lowered, as coupling.set_inputs does."""
        self._core.orders_lowered = 0
        for p, c in zip(self.ports.all, self._cports):
            for k in range(p.ext_order, c.ext_order, -1):
                self.coupling.note(f"{p.inst.name} refused input derivatives of order {k} "
                                   f"({p.inst.named('setInputDerivatives')}): order {k - 1} from "
                                   f"t = {c.lowered_at!r} s on")
            p.ext_order = c.ext_order

    def step(self, h: float) -> float:
        rc = self._lib.cw_step(self._core_ptr, h, self._taken_ptr)
        if self._core.orders_lowered:
            self._orders_lowered()
        if rc:
            self._handle(rc)
        if self.on_step is not None:
            self.on_step(self)
        return self._taken.value

    def _run_until(self, t_stop: float, on_point=None) -> None:
        native = on_point is None or (type(on_point) is Recorder and on_point.master is self
                                      and not any(isinstance(a, _DiscreteOutput) for a, _ in on_point._sources)
                                      # the core records no row without a column: time alone is Python's
                                      and (bool(on_point.outputs) or not on_point.times))
        if self.on_step is not None or not native:
            return super()._run_until(t_stop, on_point)  # the Python loop over compiled steps
        rec, columns = (self._empty_recorder, None) if on_point is None else self._native(on_point)
        rec.grid_k = -1
        rec.n_rows = rec.n_ticks = 0
        while True:
            rc = self._lib.cw_run_until(self._core_ptr, t_stop, byref(rec), self.slice_s)
            if self._core.orders_lowered:
                self._orders_lowered()
            if columns is not None:
                self._drain(on_point, rec, columns)
                on_point.check_limit(self._core.t)
            if rc == _DONE:
                return
            if rc == _CHECK_DIVERGENCE or rc == _CLOCK_EVENT:
                # Raises for an output that is not finite or too large; else
                # the point is legal after all and is recorded now, after
                # the event of the clocks there.
                if rc == _CHECK_DIVERGENCE:
                    self._handle(rc)
                self._at_core_point()
                self._lib.cw_record_point(self._core_ptr, byref(rec))
            elif rc != _BUFFER_FULL and rc != _SLICE_OVER:
                self._handle(rc)

    def _at_core_point(self) -> None:
        """The event of the clocks where a step ended (CompiledClockedMaster); none here."""

    def _run_marks(self, t_stop, marks, on_rows):
        if self.on_step is not None:
            return super()._run_marks(t_stop, marks, on_rows)  # the Python loop over compiled steps
        c, rows, width = self._core_marks(marks)
        c.tolerance = -1.0 if marks.tolerance is None else marks.tolerance
        c.max_step = self.settings.step if marks.max_step is None else marks.max_step
        c.stopped = 0
        ptr = byref(c)
        try:
            while True:
                rc = self._lib.cw_run_marks(self._core_ptr, t_stop, ptr, self.slice_s)
                if self._core.orders_lowered:
                    self._orders_lowered()
                if rc not in (_DONE, _BUFFER_FULL, _SLICE_OVER, _WATCHED):
                    self._handle(rc)  # raises, but for a divergence check that finds nothing
                if c.n_rows:
                    flat = rows[:c.n_rows * width]
                    c.n_rows = 0
                    marks.rows.extend(zip(*[iter(flat)] * width))
                    if on_rows is not None:
                        batch, marks.rows = marks.rows, []
                        on_rows(batch)
                if rc == _DONE:
                    return False
                if rc == _WATCHED or c.stopped:
                    return True
        finally:
            self._marks_out(c, marks)

    def _core_marks(self, marks):
        """The core's struct of a plan (made at its first run here), with
        the plan's place copied in; its row buffer and the row's width."""
        made = marks.__dict__.get("_core")
        if made is None or made[0] is not self:
            marks.start()
            index = {id(p): i for i, p in enumerate(self.ports.all)}
            of_inst = {id(p.inst): i for i, p in enumerate(self.ports.all)}
            width = 1 + len(marks.outputs) + len(marks.before)
            capacity = max(2, marks.rows_per_call)
            rows = (c_double * (capacity * width))()
            keep = [rows]  # the arrays live as long as the plan

            def ref(obj) -> int:
                keep.append(obj)
                return ctypes.addressof(obj)

            c = _Marks(times=ref(_array(c_double, marks.times, max(1, len(marks.times)))),
                       sets=ref(_array(c_int, map(int, marks.sets), max(1, len(marks.sets)))),
                       values=ref(_array(c_double, marks.values, max(1, len(marks.values)))),
                       in_port=ref(_array(c_int, (of_inst[id(inst)] for inst, _ in marks.inputs))),
                       in_vr=ref(_array(c_uint, (vr for _, vr in marks.inputs))),
                       out_port=ref(_array(c_int, (index[id(p)] for p, _ in marks.outputs))),
                       out_pos=ref(_array(c_int, (j for _, j in marks.outputs))),
                       prev_port=ref(_array(c_int, (index[id(p)] for p, _ in marks.before))),
                       prev_pos=ref(_array(c_int, (j for _, j in marks.before))),
                       previous=ref(_array(c_double, [], len(marks.before))),
                       watch_port=ref(_array(c_int, (index[id(p)] for p, _ in marks.watched))),
                       watch_pos=ref(_array(c_int, (j for _, j in marks.watched))),
                       seen=ref(_array(c_double, [], len(marks.watched))), rows=ctypes.addressof(rows),
                       margin=-1.0 if marks.margin is None else marks.margin,
                       period=0.0 if marks.follow is None else marks.follow[1],
                       n_in=len(marks.inputs), n_out=len(marks.outputs), n_prev=len(marks.before),
                       n_watch=len(marks.watched), capacity=capacity,
                       follow=-1 if marks.follow is None else marks.follow[0], record=int(marks.record_at_marks),
                       stop_at_change=int(marks.stop_at_change))
            made = marks._core = (self, c, rows, width, keep)
        _, c, rows, width, _ = made
        # The place, as the plan holds it (it may have run on the Python loop since).
        c.next, c.n_times = marks.next, len(marks.times)
        if marks.follow is not None and marks.times:
            ctypes.cast(c.times, POINTER(c_double))[0] = marks.times[0]
        for name, values in (("seen", marks.seen), ("previous", marks.previous)):
            arr = ctypes.cast(getattr(c, name), POINTER(c_double))
            for j, x in enumerate(values):
                arr[j] = x
        c.last_event = marks.last_event
        c.has_prev = int(marks.prev_event is not None)
        c.prev_event = 0.0 if marks.prev_event is None else marks.prev_event
        return c, rows, width

    @staticmethod
    def _marks_out(c: _Marks, marks) -> None:
        """The core's place back into the plan."""
        marks.next = c.next
        if marks.follow is not None and c.n_times:
            marks.times[:] = [ctypes.cast(c.times, POINTER(c_double))[0]]
            marks.sets[:], marks.values[:] = [False], [0.0]
        marks.seen[:] = ctypes.cast(c.seen, POINTER(c_double))[:len(marks.seen)]
        marks.previous[:] = ctypes.cast(c.previous, POINTER(c_double))[:len(marks.previous)]
        marks.last_event = c.last_event
        marks.prev_event = c.prev_event if c.has_prev else None

    def _native(self, recorder: Recorder):
        # Made once per recorder: a run is called in chunks (analyses.time_series), and systems have
        # thousands of ports; only the recorder's position is handed over at each call.
        made = self.__dict__.get("_native_made")
        if made is None or made[0] is not recorder:
            made = self._native_made = (recorder, *self._make_native(recorder))
        _, rec, columns = made
        rec.last_tick = recorder._last_tick
        rec.grid_seen = recorder._k
        return rec, columns

    def _make_native(self, recorder: Recorder):
        index = {id(p.out): i for i, p in enumerate(self.ports.all)}
        ports = [index[id(arr)] for arr, _ in recorder._sources]
        # At most about 32 MiB of rows, whatever the width (4096 rows of 100,000 columns were 3.3 GB).
        capacity = max(16, min(ROWS_PER_CALL, (1 << 22) // (len(ports) + 1)))
        rows = (c_double * (capacity * (len(ports) + 1)))()
        ticks = (c_double * ROWS_PER_CALL)()
        rec = _Recorder(col_port=self._ref(_array(c_int, ports)),
                        col_pos=self._ref(_array(c_int, (j for _, j in recorder._sources))),
                        rows=ctypes.addressof(rows), ticks=ctypes.addressof(ticks),
                        n_cols=len(ports), capacity=capacity, tick_capacity=ROWS_PER_CALL,
                        stride=recorder._stride, has_interval=int(bool(recorder._interval)),
                        tick_port=-1 if recorder._tick_port is None else index[id(recorder._tick_port.out)],
                        tick_pos=recorder._tick_pos)
        rec._buffers = (rows, ticks)
        return rec, [recorder.columns["time"]] + [recorder.columns[n] for n in recorder.names]

    @staticmethod
    def _drain(recorder: Recorder, rec: _Recorder, columns: list[list[float]]) -> None:
        rows, ticks = rec._buffers
        width = len(columns)
        flat = rows[:rec.n_rows * width]
        for c, col in enumerate(columns):
            col.extend(flat[c::width])
        recorder.ticks.extend(ticks[:rec.n_ticks])
        recorder._last_tick = rec.last_tick
        recorder._k = rec.grid_seen
        rec.n_rows = rec.n_ticks = 0

    def _handle(self, rc: int) -> None:
        """Raise the error the Python master would raise (or name a divergence)."""
        m = self._core
        if rc == _CHECK_DIVERGENCE:
            self.ports.name_divergence(m.t, self.settings.divergence_limit, last_point=m.err_t)
            return
        if rc == _ENDED:
            raise self._asked_to_end()
        if rc == _ERR_FMI:
            p = self.ports.all[m.err_port]
            if m.err_call == 0:
                raise self._step_failure(p, m.err_status, m.err_t, m.err_h)
            call, purpose = _CALLS[m.err_call]
            raise p.inst.fail(p.inst.named(call) + purpose, m.err_status, m.err_t)
        t = m.err_t
        if rc == _ERR_RATES:
            raise REFUSALS[m.err_call](t, m.err_h, self.settings.step)
        if rc == _ERR_LOOP:
            c = ctypes.cast(self._loops.loop, POINTER(_Loop))[m.err_port]
            raise self.ports.loops[m.err_port].failure(t, c.fail_why, c.fail_worst, c.fail_at, c.fail_sweeps,
                                                       c.fail_newton)
        if rc == _ERR_NO_CHECKPOINT:
            raise SimulationError(
                f"an event indicator changed sign at t = {t!r} s in a step without a checkpoint", time=t)
        if rc == _ERR_REPLAY:
            raise SimulationError(f"replay ended at t = {m.err_h!r} s instead of {t!r} s", time=t)
        if rc == _ERR_LOCATE:
            raise SimulationError(
                f"event location did not converge in (t, t+h) = ({t!r}, {t + m.err_h!r}) s", time=t)
        raise SimulationError(f"the compiled core stopped with code {rc} at t = {m.t!r} s", time=m.t)


class CompiledClockedMaster(CoreClocks, ClockedMaster, CompiledMaster):
    """``ClockedMaster`` (FMI 3.0 clocks) with its steps in the compiled core (engine/compiled_clocks.py)."""
