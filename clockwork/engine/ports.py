"""Ports: preallocated ctypes arrays of each instance's connected variables.

A port holds what the master exchanges with one instance on the hot path:
the value references and values of its connected inputs, of its connected
or recorded Real outputs and of its event indicators, and the input
derivatives. All outputs of all instances live in one buffer, so that the
divergence check is one pass. ``Ports`` also knows the orders in which the
communication step visits them (from the wiring graph).
"""

from __future__ import annotations

import ctypes
import math
from ctypes import c_double, c_int, c_uint

from ..errors import SceneError, SimulationError
from ..fmi.description import int_range, types_connect
from ..fmi.calls import WARNING
from ..fmi.contract import Instance
from .loops import Loop
from .wiring import Link, Wiring, loop_name


class Port:
    def __init__(self, inst: Instance, inputs: list[str], outputs: list[str], indicators: list[str]):
        self.inst = inst
        self.comp = inst.component
        # Indicators come last (read twice if also an output), so that the
        # master takes them all with one slice of `out`.
        self.out_names = outputs + indicators
        self.n_out = len(self.out_names)
        self.out_vr = (c_uint * max(1, self.n_out))(*[inst.variables[n].vr for n in self.out_names])
        self.out = (c_double * max(1, self.n_out))()  # rebound into the one buffer of all outputs
        self.z_pos = list(range(len(outputs), self.n_out))
        self.in_names = inputs
        self.n_in = len(inputs)
        self.in_vr = (c_uint * max(1, self.n_in))(*[inst.variables[n].vr for n in inputs])
        self.inp = (c_double * max(1, self.n_in))()
        self.der_vr = (c_uint * max(1, 2 * self.n_in))(*([inst.variables[n].vr for n in inputs] * 2))
        self.der_order = (c_int * max(1, 2 * self.n_in))(*([1] * self.n_in + [2] * self.n_in))
        self.der = (c_double * max(1, 2 * self.n_in))()
        # (input position, source port, source output position)
        self.sources: list[tuple[int, "Port", int]] = []
        # (input position, factor, offset) of the inputs whose link is not the identity
        self.scale: list[tuple[int, float, float]] = []
        # (input position, source port, source output position) added, in
        # order, to what `sources` gives that input (an OSP Sum, Link.adds)
        self.adds: list[tuple[int, "Port", int]] = []
        self.out_time = 0.0  # time at which `out` was read, s
        self.doStep, self.getReal, self.setReal = inst.c_doStep, inst.c_getReal, inst.c_setReal
        self.sent: list[float] = []  # inputs last given to the FMU (zero-order hold), to skip repeats
        self.sent_valid = False
        # Integer, Boolean, Enumeration and String links: the connected
        # outputs' values as read at out_time, and per discrete input its
        # source (port, position in that port's `dout`).
        self.dout_names: list[str] = []
        self.dout: list = []
        self.din_names: list[str] = []
        self.din_sources: list[tuple["Port", int]] = []
        self.din_sent: dict = {}  # the discrete inputs' values last set
        self._din_what = inst.named("setValues") + " of inputs"  # in messages, made once
        self.has_inputs = self.n_in > 0  # Real or discrete
        # Order of the input polynomials this FMU gets (master.extrapolation,
        # 0 where it cannot interpolate inputs; lowered where it refuses one).
        self.ext_order = 0

    def read(self, t: float) -> None:
        """Read the outputs at the communication point t."""
        if self.n_out:
            st = self.getReal(self.comp, self.out_vr, self.n_out, self.out)
            if st > WARNING:
                raise self.inst.fail(self.inst.named("getReal"), st, t)
        if self.dout_names:
            self.dout = self.inst.get_values(self.dout_names)
        self.out_time = t

    def set_discrete(self) -> None:
        """Set the discrete inputs to their sources' values (Python engine only)."""
        values = {}
        for n, (src, j) in zip(self.din_names, self.din_sources):
            x = src.dout[j]
            kind = self.inst.variables[n].type
            bounds = int_range(kind)
            if bounds and not bounds[0] <= x <= bounds[1]:
                # Integers of different sizes connect; a value the input cannot hold stops the run.
                raise SimulationError(f"connection {src.inst.name}.{src.dout_names[j]} -> {self.inst.name}.{n}: "
                                      f"the value {x} is out of the range of {kind} [{bounds[0]}, {bounds[1]}]",
                                      instance=self.inst.name)
            values[n] = x
        self.inst.set_values(values, self._din_what)
        self.din_sent = values

    def pull(self, t: float, read: bool = True) -> None:
        """Set the inputs to their sources' outputs, then read the outputs
        (unless `read` is false), at t."""
        if self.din_names:
            self.set_discrete()
        if self.n_in:
            inp = self.inp
            for k, src, j in self.sources:
                inp[k] = src.out[j]
            for k, src, j in self.adds:
                inp[k] += src.out[j]
            for k, f, o in self.scale:
                inp[k] = f * inp[k] + o
            st = self.setReal(self.comp, self.in_vr, self.n_in, inp)
            if st > WARNING:
                raise self.inst.fail(self.inst.named("setReal") + " of inputs", st, t)
            self.sent_valid = False
        if read:
            self.read(t)


def _first_positions(names: list[str]) -> dict[str, int]:
    """{name: its first position in names} (list.index for each, at once)."""
    out: dict[str, int] = {}
    for k, x in enumerate(names):
        out.setdefault(x, k)
    return out


def _unread(inst: Instance, name: str):
    """A discrete output's value before it is first read: zero, or empty text."""
    return "" if inst.variables[name].type == "String" else 0


def _arrays_together(inst: Instance, names: list[str]) -> list[str]:
    """Input names with each array's elements side by side in index order,
    where its first element is (a request of whole arrays is one fmi3 call)."""
    if not inst.arrays:
        return names
    first: dict[str, int] = {}
    for pos, n in enumerate(names):
        first.setdefault(inst.variables[n].array or n, pos)
    return sorted(names, key=lambda n: (first[inst.variables[n].array or n], inst.variables[n].index))


def link_type(instances: dict[str, Instance], link: Link) -> str:
    """The FMI type of a link's two ends (the output's, or the input's where
    that is not Real: a Float32 end goes through the discrete path);
    SceneError (bad input) where they cannot be connected."""
    a = instances[link.src].variables[link.output].type
    b = instances[link.dst].variables[link.input].type
    if not types_connect(a, b):
        raise SceneError(f"connection {link.src}.{link.output} -> {link.dst}.{link.input}: type mismatch, "
                         f"{link.src}.{link.output} is {a}, {link.dst}.{link.input} is {b}")
    return b if a == "Real" else a


def feeds(inst: Instance, name: str) -> bool:
    """True when output `name` depends directly on inputs (missing information counts as yes)."""
    v = inst.variables[name]
    return v.causality == "output" and (v.dependencies is None or len(v.dependencies) > 0)


class Ports(dict):
    """Every instance's port by instance name, the one output buffer, and
    the orders in which a communication step visits them."""

    def __init__(self, instances: dict[str, Instance], links: list[Link], wiring: Wiring,
                 extra_outputs: dict[str, list[str]] | None, event_location: bool, owner=None):
        """`owner`: the master whose settings (algebraic_loops,
        iteration_tolerance) and statistics the algebraic loops use."""
        super().__init__()
        inputs: dict[str, list[str]] = {n: [] for n in instances}
        outputs: dict[str, list[str]] = {n: [] for n in instances}
        real_links, discrete_links = [], []
        for link in links:
            kind = link_type(instances, link)
            if kind != "Real" and not link.identity:
                raise SceneError(f"connection {link.src}.{link.output} -> {link.dst}.{link.input}: a linear "
                                 f"transformation needs Real variables, these are {kind}")
            if link.adds and (kind != "Real" or not link.identity):
                raise SceneError(f"connection {link.src}.{link.output} -> {link.dst}.{link.input}: a sum adds "
                                 f"Real outputs as they are, this one is {kind} with factor {link.factor:g} and "
                                 f"offset {link.offset:g}")
            (real_links if kind == "Real" else discrete_links).append(link)
        links = real_links
        # Sets beside the lists: an instance may have 100,000 outputs, and `in` on a list made loading quadratic.
        known: dict[str, set[str]] = {n: set() for n in instances}
        for link in links:
            if not link.adds:
                inputs[link.dst].append(link.input)
            if link.output not in known[link.src]:
                known[link.src].add(link.output)
                outputs[link.src].append(link.output)
        # An input array's elements go together, in order: FMI 3.0 sets an array whole.
        inputs = {n: _arrays_together(instances[n], names) for n, names in inputs.items()}
        # Integer and Boolean outputs are discrete: read on demand, not per step.
        self.discrete_outputs: dict[str, list[str]] = {n: [] for n in instances}
        for n, names in (extra_outputs or {}).items():
            for x in (y for name in names for y in instances[n].elements.get(name, [name])):
                if instances[n].variables[x].type != "Real":
                    self.discrete_outputs[n].append(x)
                elif x not in known[n]:
                    known[n].add(x)
                    outputs[n].append(x)
        for n, inst in instances.items():
            self[n] = Port(inst, inputs[n], outputs[n], inst.event_indicators if event_location else [])
        self.buffer = (c_double * sum(max(1, p.n_out) for p in self.values()))()
        offset = 0
        for p in self.values():
            n = max(1, p.n_out)
            p.out = (c_double * n).from_buffer(self.buffer, offset * 8)
            offset += n
        dout_pos: dict[str, dict[str, int]] = {n: {} for n in instances}
        for link in discrete_links:
            dst, src = self[link.dst], self[link.src]
            at = dout_pos[link.src]
            if link.output not in at:
                at[link.output] = len(src.dout_names)
                src.dout_names.append(link.output)
                # Until the source is first read, as a Real output's buffer: zero (or empty text).
                src.dout.append(_unread(src.inst, link.output))
            dst.din_names.append(link.input)
            dst.din_sources.append((src, at[link.output]))
            dst.has_inputs = True
        self.has_discrete_links = bool(discrete_links)
        self.dout_pos = dout_pos
        # Positions by name, once per port: a sink may have thousands of inputs.
        in_pos = {n: _first_positions(p.in_names) for n, p in self.items()}
        out_pos = {n: _first_positions(p.out_names) for n, p in self.items()}
        self.out_pos = out_pos  # {instance: {output: its position in the port's `out`}}, for the recorder
        for link in links:
            dst, src = self[link.dst], self[link.src]
            k = in_pos[link.dst].get(link.input)
            if link.adds:
                if k is None or any(kk == k for kk, _, _ in dst.scale):
                    raise SceneError(f"connection {link.src}.{link.output} -> {link.dst}.{link.input}: it adds "
                                     "to a sum that no link before it starts as it is (factor 1, offset 0)")
                dst.adds.append((k, src, out_pos[link.src][link.output]))
                continue
            dst.sources.append((k, src, out_pos[link.src][link.output]))
            if not link.identity:
                dst.scale.append((k, float(link.factor), float(link.offset)))
        for p in self.values():  # in input order
            p.sources.sort(key=lambda source: source[0])
            p.scale.sort(key=lambda scale: scale[0])
            p.adds.sort(key=lambda add: add[0])  # stable: each sum's terms stay in their order

        self.all = list(self.values())
        self.first = [self[n] for n in wiring.feedthrough_only]  # stepped first: they commit modes
        self.dynamic = [self[n] for n in wiring.dynamic]
        mode = owner.settings.algebraic_loops if owner is not None else "solve"
        in_loop = {n: i for i, members in enumerate(wiring.loops) for n in members}
        loop_discrete: list[list[Link]] = [[] for _ in wiring.loops]
        for link in discrete_links:
            i = in_loop.get(link.src)
            if i is not None and in_loop.get(link.dst) == i and wiring.feedthrough_outputs[(link.src, link.output)]:
                loop_discrete[i].append(link)
        held = set(wiring.held_loops)
        self.loops = [self._loop(owner, i, wiring, loop_discrete[i], "delay" if i in held else mode, len(instances))
                      for i in range(len(wiring.loops))]
        for i in held:  # solved where the standard allows it: in Initialization Mode
            self.loops[i].solve_in_init = True
        # Output updates, in dependency order; a loop stands where its members would.
        loop_of = {p: loop for loop in self.loops for p in loop.members}
        self.order: list = []
        placed: set[int] = set()
        for n in wiring.evaluation_order:
            item = loop_of.get(self[n], self[n])
            if id(item) not in placed:
                placed.add(id(item))
                self.order.append(item)
        first = set(self.first)
        self.first_in_order = [x for x in self.order if x in first
                               or (isinstance(x, Loop) and x.mode == "solve" and not first.isdisjoint(x.members))]
        # After a step, only feedthrough outputs need an update at t + h;
        # a dynamic instance's own inputs are set when its next step starts.
        # A loop broken by a delay keeps what its members gave after their step.
        # An instance whose outputs may not be read after its inputs are set
        # (outputs_after_inputs false) keeps what it gave after its step.
        def updated(p: Port) -> bool:
            return p in first or (getattr(p.inst, "outputs_after_inputs", True) and any(
                wiring.feedthrough_outputs.get((p.inst.name, n), feeds(p.inst, n)) for n in p.out_names))

        self.final_order = [x for x in self.order if (x.mode == "solve" if isinstance(x, Loop) else updated(x))]

    def _loop(self, owner, index: int, wiring: Wiring, discrete_links: list[Link], mode: str,
              n_instances: int) -> Loop:
        """Loop `index` of the wiring; `discrete_links`: its feedthrough links that are not Real."""
        members = wiring.loops[index]
        inside = set(members)
        ports = [self[n] for n in members]
        feeding = wiring.feedthrough_outputs
        unknowns = []
        for p in ports:
            scale = {k: (f, o) for k, f, o in p.scale}
            # a summed input (Port.adds) is an unknown where any of its terms comes from inside
            inner = {k for k, src, j in p.sources + p.adds
                     if src.inst.name in inside and feeding[(src.inst.name, src.out_names[j])]}
            for k, src, j in p.sources:
                if k in inner:
                    f, o = scale.get(k, (1.0, 0.0))
                    unknowns.append((p, k, src, j, f, o, k in scale))
        discrete = []
        for link in discrete_links:
            src = self[link.src]
            discrete.append((self[link.dst], link.input, src, self.dout_pos[link.src][link.output],
                             f"{link.src}.{link.output} -> {link.dst}.{link.input}",
                             src.inst.variables[link.output].type))
        return Loop(owner, loop_name(members, wiring.loop_links[index]), ports, unknowns, discrete, mode,
                    n_instances)

    def forget_outputs(self) -> None:
        """Every output as before the first read: zero (or empty text)."""
        ctypes.memset(self.buffer, 0, ctypes.sizeof(self.buffer))
        for p in self.all:
            p.dout = [_unread(p.inst, n) for n in p.dout_names]

    def start_loops(self) -> None:
        """The loops broken by a delay start as the peers do at their next update."""
        for loop in self.loops:
            loop.starting = True

    def initializing(self, on: bool) -> None:
        """Initialization Mode begins (on) or ends: a loop solved only there
        (Loop.solve_in_init) solves while it lasts, and is read after it."""
        for loop in self.loops:
            if loop.solve_in_init:
                loop.mode = "solve" if on else "delay"
                loop.starting = False

    def refresh(self, t: float) -> None:
        """The outputs again after inputs or parameters changed between
        steps (set and read, in dependency order), where the instance allows
        a read after a set; the others show the change after their next step."""
        for x in self.order:
            if isinstance(x, Loop):
                if x.mode == "solve":
                    x.pull(t)
                else:
                    for p in x.members:
                        if getattr(p.inst, "outputs_after_inputs", True):
                            p.read(t)
            elif getattr(x.inst, "outputs_after_inputs", True):
                x.pull(t)

    def after_init(self, t: float) -> None:
        """The outputs after Initialization Mode, in dependency order: set
        and read again where the instance allows a read after a set, else
        only read (its inputs are those Initialization Mode ended with)."""
        for x in self.order:
            if isinstance(x, Loop):
                if x.mode == "solve":
                    x.pull(t)
                else:
                    for p in x.members:
                        p.read(t)
            elif getattr(x.inst, "outputs_after_inputs", True):
                x.pull(t)
            else:
                x.read(t)

    def propagate(self, ports: list[Port], t: float) -> None:
        """Set inputs from their sources and read outputs, in order, at t."""
        for p in ports:
            p.pull(t)

    def dynamic_outputs(self) -> list[float]:
        return [p.out[k] for p in self.dynamic for k in range(p.n_out)]

    def diverged(self, limit: float) -> bool:
        """One pass over every output: False while all are finite and below `limit`."""
        return not sum(map(abs, self.buffer)) < limit  # NaN fails too

    def name_divergence(self, t: float, limit: float, last_point: float | None = None) -> None:
        """Raise for the output that failed ``diverged`` (a sum of large but
        legal outputs can fail it too: then nothing); the error's
        ``last_point`` is the last good communication point, s."""
        for p in self.all:
            if sum(map(abs, p.out)) < limit:
                continue
            out = p.out
            for k in range(p.n_out):
                x = out[k]
                if not (-limit < x < limit):
                    what = "is not finite" if not math.isfinite(x) else f"exceeds the divergence limit {limit:g}"
                    e = SimulationError(f"{p.inst.name}.{p.out_names[k]} = {x!r} {what} at t = {t!r} s",
                                        time=t, instance=p.inst.name, variable=p.out_names[k])
                    e.last_point = last_point
                    raise e
