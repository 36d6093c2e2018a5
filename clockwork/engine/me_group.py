"""Connected Model Exchange FMUs as one system: a group.

Stepped alone, a Model Exchange FMU sees another's output only at
communication points (sampled, held or extrapolated by the master), so an
event that one causes in the other waits for the next point. ``MEGroup``
integrates the members together, as one Model Exchange FMU would be:

- one state vector, the concatenation of the members' (member order);
  one integrator over it (the project's Runge-Kutta pairs or CVode,
  ``me_step.ModelExchangeSteps``, the algorithm of a single FMU);
- the right-hand side sets each member's time and states, then evaluates
  the connections between members in dependency order (a link after every
  link whose value its source output depends on, by the members'
  ModelStructure), then gathers the derivatives; an algebraic loop inside
  a group is refused in one line;
- one event-indicator vector over all members, located together; at an
  event every member enters Event Mode and the event iteration runs
  across members: the connections (of every type) are propagated, every
  member updates its discrete states, until no member asks for another
  iteration and no connected value changed; the members' time events are
  merged (the earliest);
- towards the rest of the scene the group is one instance that implements
  the contract (fmi/contract.py), as ``model_exchange.MEInstance`` does:
  its variables are the members' as ``member.variable``, its continuous
  inputs those no member feeds (with the master's polynomials between
  communication points), its FMU state the members' states together.

``engine/system.py`` forms the groups (``form_groups``): each set of Model
Exchange instances joined by connections becomes one group, unless
``master.me_groups = false``. The compiled core runs a group as it runs
one Model Exchange FMU: its wrapper (src_c/master/cw_me.c) on the group's
``_ME``, whose calls go to src_c/master/cw_me_group.c, the twin of the
calls here, over the struct ``_Group`` both share (which connections need
evaluating and the values last set). The core evaluates Real, Integer,
Enumeration and Boolean connections (through the get and set each
member's face hands over, ``core_value_calls``); a group with another
(String; Real to or from an integral type) runs on the Python engine
(``compiled_reason``).
"""

from __future__ import annotations

import ctypes
import math
from ctypes import Structure, byref, c_double, c_int, c_uint, c_void_p
from dataclasses import replace
from pathlib import Path

from ..errors import SceneError, SimulationError
from ..fmi.calls import OK, WARNING
from ..fmi.contract import Instance
from .me_step import CONTINUOUS, EVENT, INITIALIZATION, SOLVERS, ModelExchangeSteps
from .model_exchange import MEInstance, MEOptions, _ME
from .wiring import Link

# FMI 2.0 numbers value references per base type: a group's table keys them so.
_TYPE_CLASS = {"Real": 0, "Integer": 1, "Enumeration": 1, "Boolean": 2, "String": 3}
# Types whose values a connection carries as integers (the core's too).
_INTEGRAL = ("Integer", "Enumeration", "Boolean")


class _GroupNames:
    """The group's names of its calls in messages (its members' first face's)."""

    CORE_CALLS_TABLE = "cwmg_calls"  # cw_me_group.c's table: the group's calls whose shape differs

    def __init__(self, face):
        self.CALL_NAMES = dict(face.CALL_NAMES, doStep="the Model Exchange group's step")
        self.NAMES = face.NAMES


class _Group(Structure):
    """What the group shares with the compiled core (cw_me_group.c's
    cw_me_group, same layout): its members, its value references, its
    connections and the values last set through them."""

    _fields_ = [(n, c_void_p) for n in (
        "me", "members", "member_state", "offsets", "vr_member", "vr_own", "c_src", "c_dst", "c_src_vr",
        "c_dst_vr", "c_continuous", "c_identity", "c_factor", "c_offset", "c_last", "c_has_last",
        "c_get", "c_set", "c_get_shape", "c_set_shape", "c_last_int")] + [
        (n, c_int) for n in ("n_members", "n_conns", "dirty", "pad_")]


class _Conn:
    """A connection inside the group, bound to its members' calls; the
    value last set is the group's (``_Group.c_last`` or ``c_last_int``, at
    ``index``), but for a String."""

    def __init__(self, index: int, link: Link, src: MEInstance, dst: MEInstance):
        self.index = index
        self.link = link
        self.src, self.dst = src, dst
        sv, dv = src.variables[link.output], dst.variables[link.input]
        self.real = sv.type == "Real" and dv.type == "Real"
        self.integral = sv.type in _INTEGRAL and dv.type in _INTEGRAL
        # In continuous-time mode only continuous Real inputs may be set.
        self.continuous = self.real and dv.variability == "continuous"
        # The compiled core's get and set of an integral connection: (get, set, get's shape, set's shape).
        got = src.face.core_value_calls(sv) if self.integral else None
        put = dst.face.core_value_calls(dv) if self.integral else None
        self.core_calls = (got[0], put[1], got[2], put[2]) if got and put else None
        self.src_vr = (c_uint * 1)(sv.vr)
        self.dst_vr = (c_uint * 1)(dv.vr)
        self.buf = (c_double * 1)()
        self.last = None  # the value last set: where it is neither Real nor integral (the Python engine's only)


def _ordered(name: str, links: list[Link], members: dict[str, MEInstance]) -> list[Link]:
    """The links in dependency order: each after the links into the inputs
    its source output depends on directly. SceneError for a loop."""
    into: dict[tuple[str, str], Link] = {(k.dst, k.input): k for k in links}

    def needs(k: Link) -> list[Link]:
        v = members[k.src].variables[k.output]
        deps = v.dependencies
        if deps is None:  # no dependency information: every input
            deps = [n for n, x in members[k.src].variables.items() if x.causality == "input"]
        return [into[(k.src, d)] for d in deps if (k.src, d) in into]

    done: list[Link] = []
    state: dict[int, int] = {}  # 1: on the path, 2: done

    def visit(k: Link, path: list[Link]) -> None:
        s = state.get(id(k))
        if s == 2:
            return
        if s == 1:
            loop = path[path.index(k):]
            through = ", ".join(f"{x.src}.{x.output} -> {x.dst}.{x.input}" for x in loop)
            raise SceneError(f"the Model Exchange group {name}: an algebraic loop inside it (through {through}) "
                             "is not supported; expected connections without a loop of direct feedthrough, or "
                             "master.me_groups = false (the FMUs stepped apart)")
        state[id(k)] = 1
        for d in needs(k):
            visit(d, path + [k])
        state[id(k)] = 2
        done.append(k)

    for k in links:
        visit(k, [])
    return done


class MEGroup(MEInstance):
    """Connected Model Exchange instances as one (see the module's docstring).
    `members`: instantiated MEInstances, in order; `links`: the connections
    between them (member names)."""

    joins_me_group = False  # a group is not a member of another

    qualified_names = True  # its variables are "member.variable": recorded under those names

    def __init__(self, name: str, members: list[MEInstance], links: list[Link], options: MEOptions | None = None):
        # Not MEInstance.__init__: the group reads no FMU of its own.
        self.name = name
        self.members = list(members)
        by_name = {m.name: m for m in self.members}
        self.path = Path(name)
        self.md = None
        self.model_name = f"Model Exchange group {name}"
        self.messages = []
        self._slave = None
        self._state = ctypes.c_void_p()
        self.face = _GroupNames(self.members[0].face)
        self.CALL_NAMES = self.face.CALL_NAMES
        self.options = options or MEOptions()
        if self.options.solver not in SOLVERS:
            raise SceneError(f"master.me_solver = {self.options.solver!r}: expected one of "
                             f"{', '.join(map(repr, SOLVERS))}")
        self.default_tolerance = None
        self.outputs_after_inputs = True
        self.can_get_set_state = all(m.can_get_set_state for m in self.members)
        needs_completed = any(m.steps.needs_completed for m in self.members)
        self._conns = [_Conn(i, k, by_name[k.src], by_name[k.dst])
                       for i, k in enumerate(_ordered(name, links, by_name))]
        other = next((c.link for c in self._conns if not (c.real or c.core_calls)), None)
        self.compiled_reason = None if other is None else (
            f"the compiled core evaluates a Model Exchange group's Real, Integer and Boolean connections only "
            f"({name}: {other.src}.{other.output} -> {other.dst}.{other.input}): the Python engine runs it")
        fed = {(k.dst, k.input) for k in links}
        # The group's value references: one per (member, type class, member's vr).
        self._table: list[tuple[MEInstance, int, str]] = []  # group vr -> (member, its vr, its type)
        numbers: dict[tuple[int, int, int], int] = {}
        variables = {}
        for i, m in enumerate(self.members):
            for vname, v in m.variables.items():
                key = (i, _TYPE_CLASS.get(v.type, 4), v.vr)
                gvr = numbers.get(key)
                if gvr is None:
                    gvr = numbers[key] = len(self._table)
                    self._table.append((m, v.vr, v.type))
                deps = None if v.dependencies is None else [f"{m.name}.{d}" for d in v.dependencies]
                variables[f"{m.name}.{vname}"] = replace(v, name=f"{m.name}.{vname}", vr=gvr, dependencies=deps)
        self.variables = variables
        self._owners = {f"{m.name}.{x}": (m, x) for m in self.members for x in m.variables}
        # Slices of the state and indicator vectors, per member.
        self._offsets = []
        n = nz = 0
        for m in self.members:
            self._offsets.append((n, m.me.n, nz, m.me.nz))
            n += m.me.n
            nz += m.me.nz
        # Continuous inputs facing the scene: those no member feeds.
        inputs = []
        for m in self.members:
            for k in range(m.me.n_in):
                vr = m.steps.in_vr[k]
                vname = next(x for x, v in m.variables.items() if v.vr == vr and v.type == "Real"
                             and v.causality == "input")
                if (m.name, vname) not in fed:
                    inputs.append((f"{m.name}.{vname}", m.steps.u0[k]))
        n_in = len(inputs)
        self.continuous_inputs = {}
        for k, (qname, _) in enumerate(inputs):
            self.continuous_inputs.setdefault(variables[qname].vr, k)
        # States: their group value references (output derivatives of outputs that are states).
        state_vr, der_state = [], []
        for m, (off, mn, _, _) in zip(self.members, self._offsets):
            names = {v.vr: x for x, v in m.variables.items() if v.type == "Real"}
            for i in range(mn):
                state_vr.append(variables[f"{m.name}.{names[m.steps.state_vr[i]]}"].vr)
                der_state.append(m.steps.der_state[i] + off if m.steps.der_state[i] >= 0 else -1)
        outputs_states = [der_state[state_vr.index(v.vr)] for v in variables.values()
                          if v.causality == "output" and v.type == "Real" and v.vr in state_vr]
        self.max_output_derivative_order = max((2 if d >= 0 else 1 for d in outputs_states), default=0)
        self.can_interpolate_inputs = n_in > 0
        self.event_indicators = []
        self.state_names = [f"{m.name}.{s}" for m in self.members for s in m.state_names]

        self.me = _ME(n=n, nz=nz, n_in=n_in, solver=SOLVERS[self.options.solver],
                      event_time_tolerance=float(self.options.event_time_tolerance),
                      needs_completed=int(needs_completed))
        self.steps = ModelExchangeSteps(self.me, [variables[q].vr for q, _ in inputs], state_vr, der_state,
                                        needs_completed)
        for k, (_, start) in enumerate(inputs):
            self.steps.u0[k] = start
        self._core = None
        self._share()
        self._dirty = True
        self._reset_wrapper()
        self._bind_group()

    def _share(self) -> None:
        """The struct shared with the compiled core (``_Group``; the
        group's ``_ME`` arrays are its ModelExchangeSteps'): whichever
        engine steps, the other sees the same connections evaluated and the
        same values last set."""
        conns, members = self._conns, self.members
        index = {id(m): i for i, m in enumerate(members)}
        keep = self._shared = []

        def array(ctype, values):
            values = list(values)
            a = (ctype * max(1, len(values)))(*values)
            keep.append(a)
            return ctypes.addressof(a)

        g = self._g = _Group(n_members=len(members), n_conns=len(conns), dirty=1)
        g.members = array(c_void_p, (ctypes.addressof(m.me) for m in members))
        g.member_state = array(c_void_p, (ctypes.addressof(m._state) for m in members))
        g.offsets = array(c_int, (k for off in self._offsets for k in off))
        g.vr_member = array(c_int, (index[id(m)] for m, _, _ in self._table))
        g.vr_own = array(c_uint, (vr for _, vr, _ in self._table))
        g.c_src = array(c_int, (index[id(c.src)] for c in conns))
        g.c_dst = array(c_int, (index[id(c.dst)] for c in conns))
        g.c_src_vr = array(c_uint, (c.src_vr[0] for c in conns))
        g.c_dst_vr = array(c_uint, (c.dst_vr[0] for c in conns))
        g.c_continuous = array(c_int, (int(c.continuous) for c in conns))
        g.c_identity = array(c_int, (int(c.link.identity) for c in conns))
        g.c_factor = array(c_double, (c.link.factor for c in conns))
        g.c_offset = array(c_double, (c.link.offset for c in conns))
        g.c_get = array(c_void_p, (c.core_calls[0] if c.core_calls else None for c in conns))
        g.c_set = array(c_void_p, (c.core_calls[1] if c.core_calls else None for c in conns))
        g.c_get_shape = array(c_int, (c.core_calls[2] if c.core_calls else 0 for c in conns))
        g.c_set_shape = array(c_int, (c.core_calls[3] if c.core_calls else 0 for c in conns))
        self._last = (c_double * max(1, len(conns)))()
        self._last_int = (ctypes.c_longlong * max(1, len(conns)))()
        self._has_last = (c_int * max(1, len(conns)))()
        g.c_last, g.c_last_int = ctypes.addressof(self._last), ctypes.addressof(self._last_int)
        g.c_has_last = ctypes.addressof(self._has_last)

    @property
    def _dirty(self) -> bool:
        return bool(self._g.dirty)

    @_dirty.setter
    def _dirty(self, value: bool) -> None:
        self._g.dirty = int(value)

    def _forget_values(self) -> None:
        """No value set through a connection yet (setup, reset, a restored state)."""
        for c in self._conns:
            c.last = None
            self._has_last[c.index] = 0

    # -- the group's calls --------------------------------------------------------

    def _bind_group(self) -> None:
        """The calls of the algorithm (me_step) and of the contract, over the members."""
        self.component = None
        self.steps.set_time = self._g_set_time
        self.steps.set_states = self._g_set_states
        self.steps.get_derivatives = self._g_get_derivatives
        self.steps.get_indicators = self._g_get_indicators
        self.steps.get_states = self._g_get_states
        self.steps.get_nominals = self._g_get_nominals
        self.steps.enter_event = self._g_enter_event
        self.steps.enter_continuous = self._g_enter_continuous
        self.steps.update = self._g_update
        self.steps.completed_step = self._g_completed
        self.steps.set_inputs = lambda vr, n, v: self._g_set_real(None, vr, n, v)
        self._fmu_set_real = self._g_set_real
        self._fmu_get_state = self._g_get_state
        self._fmu_set_state = self._g_set_state
        self._set_values_now = self._g_set_values
        self.c_getReal = self._g_get_real
        self.c_setReal = self._set_real
        self.c_setInputDerivatives = self._set_input_derivatives
        self.c_getOutputDerivatives = self._output_derivatives
        self.c_getState = self._get_state
        self.c_setState = self._set_state
        self.c_freeState = lambda c, s: OK
        self.c_doStep = self.steps.do_step

    def instantiate(self) -> None:
        """The members are instantiated (engine/system.py makes the group of them)."""
        self._slave = self.members

    def _each(self, call) -> int:
        st = OK
        for m in self.members:
            st = max(st, call(m))
            if st > WARNING:
                return st
        return st

    def _g_set_time(self, t: float) -> int:
        self._dirty = True
        return self._each(lambda m: m.steps.set_time(t))

    def _g_set_states(self, x, n: int) -> int:
        self._dirty = True
        st = OK
        for m, (off, mn, _, _) in zip(self.members, self._offsets):
            if not mn:
                continue
            buf = m.steps.xbuf
            for i in range(mn):
                buf[i] = x[off + i]
            st = max(st, m.steps.set_states(buf, mn))
            if st > WARNING:
                return st
        return st

    def _propagate(self, every: bool) -> tuple[int, bool]:
        """The connections inside the group, in dependency order: (status,
        whether a value changed). `every`: all of them (Event and
        Initialization Mode), else those into continuous Real inputs."""
        changed = False
        for c in self._conns:
            if not (every or c.continuous):
                continue
            k = c.link
            if c.real:
                st = c.src.c_getReal(c.src.component, c.src_vr, 1, c.buf)
                if st > WARNING:
                    return st, changed
                value = c.buf[0] if k.identity else k.factor * c.buf[0] + k.offset
                i = c.index
                had = self._has_last[i]
                if not had or value != self._last[i]:
                    c.buf[0] = value
                    st = c.dst.face.set_real(c.dst.component, c.dst_vr, 1, c.buf)
                    if st > WARNING:
                        return st, changed
                    changed = changed or bool(had)
                    self._last[i], self._has_last[i] = value, 1
            else:  # other types: by name, through the members' typed calls (Event Mode only)
                value = c.src.get_values([k.output])[0]
                i = c.index
                had = bool(self._has_last[i]) if c.integral else c.last is not None
                if not had or value != (self._last_int[i] if c.integral else c.last):
                    c.dst._set_values_now({k.input: value}, f"the group's connection {k.src}.{k.output} -> "
                                                            f"{k.dst}.{k.input}", SimulationError)
                    changed = changed or had
                    if c.integral:
                        self._last_int[i], self._has_last[i] = int(value), 1
                    else:
                        c.last = value
        self._dirty = False
        return OK, changed

    def _fresh(self) -> int:
        """The connections up to date before a member is read."""
        if not self._dirty:
            return OK
        return self._propagate(self.me.mode != CONTINUOUS)[0]

    def _g_get_derivatives(self, dx, n: int) -> int:
        st = self._fresh()
        if st > WARNING:
            return st
        for m, (off, mn, _, _) in zip(self.members, self._offsets):
            if not mn:
                continue
            st = max(st, m.steps.get_derivatives(m.steps.dx, mn))
            if st > WARNING:
                return st
            for i in range(mn):
                dx[off + i] = m.steps.dx[i]
        return st

    def _g_get_indicators(self, z, nz: int) -> int:
        st = self._fresh()
        if st > WARNING:
            return st
        for m, (_, _, off, mz) in zip(self.members, self._offsets):
            if not mz:
                continue
            st = max(st, m.steps.get_indicators(m.steps.z, mz))
            if st > WARNING:
                return st
            for i in range(mz):
                z[off + i] = m.steps.z[i]
        return st

    def _gather(self, x, fetch, scratch: str) -> int:
        st = OK
        for m, (off, mn, _, _) in zip(self.members, self._offsets):
            if not mn:
                continue
            buf = getattr(m.steps, scratch)
            st = max(st, fetch(m)(buf, mn))
            if st > WARNING:
                return st
            for i in range(mn):
                x[off + i] = buf[i]
        return st

    def _g_get_states(self, x, n: int) -> int:
        return self._gather(x, lambda m: m.steps.get_states, "xw")

    def _g_get_nominals(self, x, n: int) -> int:
        return self._gather(x, lambda m: m.steps.get_nominals, "nominal")

    def _g_enter_event(self) -> int:
        self._dirty = True
        return self._each(lambda m: m.steps.enter_event())

    def _g_enter_continuous(self) -> int:
        self._dirty = True
        return self._each(lambda m: m.steps.enter_continuous())

    def _g_update(self):
        """One event iteration across the members: the connections, every
        member's update, the connections again; another iteration is needed
        where a member asks for one or a connected value changed."""
        st, _ = self._propagate(True)
        if st > WARNING:
            return st, False, False, False, False, False, 0.0
        need = term = nominals = values = defined = False
        next_time = math.inf
        for m in self.members:
            s, n_, t_, nom, val, dfd, nxt = m.steps.update()
            st = max(st, s)
            if s > WARNING:
                return st, False, False, False, False, False, 0.0
            need, term, nominals, values = need or n_, term or t_, nominals or nom, values or val
            if dfd:
                defined = True
                next_time = min(next_time, nxt)
        s, changed = self._propagate(True)
        st = max(st, s)
        return st, need or changed, term, nominals, values, defined, next_time

    def _g_completed(self):
        enter = term = False
        st = OK
        for m in self.members:
            if not m.steps.needs_completed:
                continue
            s, e, t = m.steps.completed_step()
            st = max(st, s)
            if s > WARNING:
                return st, False, False
            enter, term = enter or e, term or t
        return st, enter, term

    def _g_get_state(self, comp, state) -> int:
        return self._each(lambda m: m._fmu_get_state(m.component, byref(m._state)))

    def _g_set_state(self, comp, state) -> int:
        self._dirty = True
        self._forget_values()  # the members' inputs are restored with them: set again
        return self._each(lambda m: m._fmu_set_state(m.component, m._state))

    # -- values by group value reference and by name ----------------------------------

    def _g_get_real(self, comp, vr, n, out) -> int:
        st = self._fresh()
        if st > WARNING:
            return st
        one_vr, one = (c_uint * 1)(), (c_double * 1)()
        for j in range(n):
            m, mvr, _ = self._table[vr[j]]
            one_vr[0] = mvr
            st = max(st, m.c_getReal(m.component, one_vr, 1, one))
            if st > WARNING:
                return st
            out[j] = one[0]
        return st

    def _g_set_real(self, comp, vr, n, values) -> int:
        self._dirty = True
        st = OK
        one_vr, one = (c_uint * 1)(), (c_double * 1)()
        for j in range(n):
            m, mvr, _ = self._table[vr[j]]
            one_vr[0], one[0] = mvr, values[j]
            st = max(st, m.face.set_real(m.component, one_vr, 1, one))
            if st > WARNING:
                return st
        return st

    def _split(self, names) -> list[tuple[MEInstance, str]]:
        """(member, its variable) of each "member.variable"."""
        out = []
        for q in names:
            found = self._owners.get(q)
            if found is None:
                raise SimulationError(f"{self.name}: no variable {q!r} (expected member.variable)")
            out.append(found)
        return out

    def _g_set_values(self, values: dict, what: str, error) -> None:
        self._dirty = True
        for (m, var), value in zip(self._split(values), values.values()):
            m._set_values_now({var: value}, what, error)

    def get_values(self, names):
        self._fresh()
        return [m.get_values([var])[0] for m, var in self._split(names)]

    def get_real(self, names):
        self._fresh()
        return [m.get_real([var])[0] for m, var in self._split(names)]

    def get_integer(self, names):
        self._fresh()
        return [m.get_integer([var])[0] for m, var in self._split(names)]

    def get_boolean(self, names):
        self._fresh()
        return [m.get_boolean([var])[0] for m, var in self._split(names)]

    def get_string(self, names):
        self._fresh()
        return [m.get_string([var])[0] for m, var in self._split(names)]

    # -- lifecycle ----------------------------------------------------------------

    def setup(self, start: float, parameters: dict, tolerance: float | None = None) -> None:
        """Each member's setup with its parameters ("member.variable"), then the group's integrator."""
        per: dict[str, dict] = {m.name: {} for m in self.members}
        for (m, var), value in zip(self._split(parameters), parameters.values()):
            per[m.name][var] = value
        for m in self.members:
            m.setup(start, per[m.name], tolerance)
        self._setup_wrapper(1, min(m.me.rtol for m in self.members), start)
        self.me.mode = INITIALIZATION
        self._dirty = True
        self._forget_values()

    def exit_init(self) -> None:
        st, _ = self._propagate(True)
        self.check(st, "the group's connections in Initialization Mode")
        for m in self.members:
            m.check(m.face.exit_init(m.component), m.named("exitInit"))
        self.me.mode = EVENT
        self.check(self._exit_init(OK), self.named("exitInit"))

    def reset(self) -> None:
        for m in self.members:
            m.reset()
        self._reset_wrapper()
        self._dirty = True
        self._forget_values()
        del self.messages[:]

    def set_values(self, values, what=None, error=SimulationError) -> None:
        if self.me.mode == CONTINUOUS and any(self.variables[q].vr not in self.continuous_inputs for q in values):
            what = what or self.CALL_NAMES["setValues"]
            self.check(self.steps.enter_event(), "enterEventMode", self.me.time)
            self.me.mode = EVENT
            try:
                self._g_set_values(values, what, error)
            finally:
                st = self.steps.settle("input_events")
            self.check(st, what, self.me.time, error)
            return
        self._g_set_values(values, what or self.CALL_NAMES["setValues"], error)

    def last_message(self) -> str:
        own = super().last_message() if self.messages else ""
        return own or next((t for t in (m.last_message() for m in self.members) if t), "")

    def crash(self):
        return next((c for c in (m.crash() for m in self.members) if c is not None), None)

    def statistics(self) -> dict:
        out = super().statistics()
        out["interface"] = "model-exchange (group)"
        out["members"] = [m.name for m in self.members]
        return out

    def clock_table(self):
        """None: the members' clocks are refused as each member's wrapper refuses them."""
        for m in self.members:
            m.clock_table()
        return None

    def core_state(self, lib) -> int:
        """The group's ``_ME`` made ready for the compiled core's wrapper,
        its calls the group's (cw_me_group.c's cwmg_bind), its members'
        ``_ME`` ready for their calls tables."""
        if self.compiled_reason:
            raise SimulationError(self.compiled_reason)
        if self._core is None:
            for m in self.members:
                m.core_state(lib)
            lib.cwmg_bind.argtypes = [c_void_p, c_void_p]
            lib.cwmg_bind.restype = None
            lib.cwmg_bind(ctypes.addressof(self.me), ctypes.addressof(self._g))
        return super().core_state(lib)

    def _free_instance(self) -> None:
        from . import cvode
        if self.me.cv_mem or self.me.cv_ctx:
            cvode.free(self.me)
        for m in self.members:
            m.free()

    def __reduce_ex__(self, protocol):
        raise SimulationError(f"the Model Exchange group {self.name} cannot be pickled or copied")


def plan_groups(instances: dict[str, Instance], links: list[Link]) -> list[tuple[str, list[str], list[Link]]]:
    """The groups the Model Exchange instances among `instances` form (each
    set joined by links): (the group's name, its members in scene order,
    the links between them in dependency order). SceneError for an
    algebraic loop inside one. Reads no FMU: the scene's validation asks it too."""
    me = {n for n, inst in instances.items() if inst.joins_me_group}
    parent = {n: n for n in me}

    def root(n):
        while parent[n] != n:
            parent[n] = parent[parent[n]]
            n = parent[n]
        return n

    for k in links:
        if k.src in me and k.dst in me and k.src != k.dst:
            parent[root(k.src)] = root(k.dst)
    sets: dict[str, list[str]] = {}
    for n in instances:
        if n in me:
            sets.setdefault(root(n), []).append(n)
    plans = []
    for names in sets.values():
        if len(names) < 2:
            continue
        name = "+".join(names)
        inner = [k for k in links if k.src in names and k.dst in names]
        summed = next((k for k in links if k.adds and k.dst in names), None)
        if summed is not None:  # a member's inputs each come from one output at every stage
            raise SceneError(f"{summed.dst}.{summed.input}: not supported: a sum (an OSP Sum) into the Model "
                             f"Exchange group {name} (master.me_groups = false steps its members alone)")
        plans.append((name, names, _ordered(name, inner, {n: instances[n] for n in names})))
    return plans


def form_groups(instances: dict[str, Instance], links: list[Link],
                options: MEOptions | None = None) -> tuple[dict[str, Instance], list[Link], dict[str, str]]:
    """Each set of Model Exchange instances joined by links, as one group:
    (the instances, groups in their first member's place; the links that
    remain, re-addressed to the groups' "member.variable"; {member: group})."""
    plans = plan_groups(instances, links)
    if not plans:
        return instances, links, {}
    group_of = {}
    made = {}
    for gname, names, inner in plans:
        made[names[0]] = MEGroup(gname, [instances[n] for n in names], inner, options)
        made[names[0]].instantiate()
        for n in names:
            group_of[n] = gname
    out = {}
    for n, inst in instances.items():
        if n in made:
            out[made[n].name] = made[n]
        elif n not in group_of:
            out[n] = inst
    rest = []
    for k in links:
        gs, gd = group_of.get(k.src), group_of.get(k.dst)
        if gs is not None and gs == gd:
            continue
        rest.append(Link(gs or k.src, f"{k.src}.{k.output}" if gs else k.output,
                         gd or k.dst, f"{k.dst}.{k.input}" if gd else k.input, k.factor, k.offset, k.adds))
    return out, rest, group_of
