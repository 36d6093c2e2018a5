"""The wiring graph: who feeds whom, and in which order outputs are updated.

An instance is *feedthrough-only* when every output the scene connects
depends directly on its inputs (ModelStructure dependencies): the
escapements and the drag. Such instances carry no dynamics the master must
step in a Gauss-Seidel sequence; they are stepped first in a communication
step, while their inputs still hold the values of the step's start, which
is when they commit discrete modes. Outputs are then propagated at the new
communication point in dependency order. Instances whose feedthrough
outputs feed each other form an algebraic loop (a strongly connected
component of the feedthrough graph), which engine/loops.py brings up to date.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from ..errors import SceneError
from ..fmi.description import link_shape_problem
from ..fmi.contract import Instance
from .names import split_link, split_ref


@dataclass(frozen=True)
class Link:
    """The input receives factor * output + offset (a Real link's linear
    transformation or unit conversion; the identity is never computed).
    With `adds`, the output is added to what the links before it give the
    same input, in their order (an OSP Sum: libcosim's in[0] + in[1] + ...)."""

    src: str
    output: str
    dst: str
    input: str
    factor: float = 1.0
    offset: float = 0.0
    adds: bool = False

    @property
    def identity(self) -> bool:
        return self.factor == 1.0 and self.offset == 0.0


def parse_link(text: str, instances: Mapping[str, object] | None = None) -> Link:
    """'src.output -> dst.input' as a Link; instance names are matched
    against `instances` (names -> variables), longest first (engine.names)."""
    ends = split_link(text)
    refs = [split_ref(e, instances) if instances is not None else _first_dot(e) for e in ends or ()]
    if ends is None or None in refs:
        raise SceneError(f"connection {text!r}: expected 'instance.output -> instance.input'")
    (a, b), (c, d) = refs
    return Link(a, b, c, d)


def _first_dot(ref: str) -> tuple[str, str] | None:
    a, dot, b = ref.partition(".")
    return (a, b) if dot and a and b else None


@dataclass
class Wiring:
    links: list[Link]
    feedthrough_only: list[str]  # instances stepped first (mode commit)
    dynamic: list[str]  # instances stepped in Gauss-Seidel/Jacobi order
    evaluation_order: list[str]  # order of output updates at a communication point
    feedthrough_outputs: dict[tuple[str, str], bool]  # (instance, output) -> has direct feedthrough
    # Algebraic loops: the strongly connected components of the feedthrough
    # graph (or one instance feeding itself), each with its members in
    # instance order; consecutive in evaluation_order.
    loops: list[list[str]] = field(default_factory=list)
    loop_links: list[list[Link]] = field(default_factory=list)  # per loop, the feedthrough links inside it
    # Loops to be solved (algebraic_loops = "solve") with a member whose
    # outputs may not be read after its inputs are set without a step:
    # solved in Initialization Mode only, broken by a one-step delay in the
    # steps (their indices in `loops`).
    held_loops: list[int] = field(default_factory=list)


def expand_arrays(instances: dict[str, Instance], links: list[Link]) -> list[Link]:
    """Links between FMI 3.0 arrays as links between their elements, in
    order (arrays of the same shape only); SceneError where shapes differ or
    where an input array would be connected in part (FMI 3.0 sets an array
    whole)."""
    if not any(getattr(inst, "arrays", None) for inst in instances.values()):  # (tests wire stand-ins too)
        return list(links)
    out = []
    for link in links:
        src, dst = instances[link.src], instances[link.dst]
        s, d = src.variables[link.output], dst.variables[link.input]
        if not s.shape and not d.shape:
            out.append(link)
            continue
        problem = link_shape_problem(f"{link.src}.{link.output}", s, f"{link.dst}.{link.input}", d)
        if problem:
            raise SceneError(f"connection {link.src}.{link.output} -> {link.dst}.{link.input}: {problem}")
        for a, b in zip(src.elements[link.output], dst.elements[link.input]):
            out.append(Link(link.src, a, link.dst, b, link.factor, link.offset))
    connected: dict[tuple[str, str], list[str]] = {}
    for link in out:
        v = instances[link.dst].variables[link.input]
        if v.array is not None:
            connected.setdefault((link.dst, v.array), []).append(link.input)
    for (dst, array), names in connected.items():
        size = instances[dst].arrays[array][1]
        if len(set(names)) < size:
            raise SceneError(f"connection to {dst}.{names[0]}: {dst}.{array} is an input array of {size} values "
                             f"and {len(set(names))} of them are connected; FMI 3.0 sets an array whole: "
                             f"connect {dst}.{array} (or every element of it)")
    return out


def build(instances: dict[str, Instance], links: list[Link], step_order: list[str] | None = None,
          algebraic_loops: str = "solve") -> Wiring:
    """The wiring of `links` between `instances` (links between whole arrays
    become links between their elements: ``Wiring.links``). With
    algebraic_loops = "delay", the members of a loop are stepped as dynamic
    instances whose outputs are read once, after their step (a one-step
    delay)."""
    links = expand_arrays(instances, links)
    feeds: dict[tuple[str, str], bool] = {}
    for link in links:
        var = instances[link.src].variables[link.output]
        # Missing dependency information means "depends on all inputs".
        feeds[(link.src, link.output)] = var.dependencies is None or len(var.dependencies) > 0

    names = list(instances)
    # Successors over feedthrough edges only: a source must be evaluated
    # before an output of its destination that depends on it.
    edges: dict[str, set[str]] = {n: set() for n in names}
    for link in links:
        if feeds[(link.src, link.output)]:
            edges[link.src].add(link.dst)
    components = strongly_connected(names, {n: sorted(e) for n, e in edges.items()})
    rank = {n: i for i, n in enumerate(names)}
    order: list[str] = []
    loops: list[list[str]] = []
    for comp in reversed(components):  # emitted sinks first
        comp = sorted(comp, key=rank.__getitem__)
        if len(comp) > 1 or comp[0] in edges[comp[0]]:
            loops.append(comp)
        order += comp
    in_loop = {n: i for i, loop in enumerate(loops) for n in loop}
    loop_links: list[list[Link]] = [[] for _ in loops]
    for link in links:
        i = in_loop.get(link.src)
        if i is not None and feeds[(link.src, link.output)] and in_loop.get(link.dst) == i:
            loop_links[i].append(link)

    connected_outputs: dict[str, list[str]] = {}
    for link in links:
        connected_outputs.setdefault(link.src, []).append(link.output)
    feedthrough_only = [
        n for n in names
        if n in connected_outputs and all(feeds[(n, o)] for o in connected_outputs[n])
    ]
    feedthrough_only += [n for n in names if n not in connected_outputs and not _has_free_outputs(instances[n])]
    # The call sequence (FMI 2.0 4.2.4, FMI 3.0 Step Mode): an instance whose
    # outputs may not be read after its inputs are set without a step
    # (Instance.outputs_after_inputs false) is stepped as a dynamic one:
    # inputs set, step, outputs read; never updated at t + h.
    strict = {n for n, inst in instances.items() if not getattr(inst, "outputs_after_inputs", True)}
    held_loops = [i for i, loop in enumerate(loops) if algebraic_loops == "solve" and not strict.isdisjoint(loop)]
    delayed = set(in_loop) if algebraic_loops == "delay" else {n for i in held_loops for n in loops[i]}
    # Stepped with the inputs of the step's start, read after the step:
    # what a delayed loop member gives is one step old when it arrives.
    demoted = [n for n in feedthrough_only if n in strict and n not in delayed]
    feedthrough_only = [n for n in feedthrough_only if n not in delayed and n not in strict]
    first = set(feedthrough_only)
    dynamic = [n for n in (step_order or names) if n not in first]
    if demoted and step_order is None:
        _after_sources(dynamic, [n for n in order if n in set(demoted)], links, first)
    return Wiring(links, feedthrough_only, dynamic, order, feeds, loops, loop_links, held_loops)


def _after_sources(dynamic: list[str], moved: list[str], links: list[Link], first: set[str]) -> None:
    """Move each of `moved` (feedthrough instances stepped as dynamic ones,
    in dependency order) right after the last instance of `dynamic` it
    reads, directly or through feedthrough-only instances, where that one
    steps later: in Gauss-Seidel order it then steps with its sources' new
    values, as the peers' conforming sequence gives them."""
    feeders: dict[str, set[str]] = {}
    for link in links:
        feeders.setdefault(link.dst, set()).add(link.src)
    for n in moved:
        sources, seen, stack = set(), set(), list(feeders.get(n, ()))
        while stack:
            s = stack.pop()
            if s in seen:
                continue
            seen.add(s)
            if s in first:
                stack.extend(feeders.get(s, ()))
            elif s != n:
                sources.add(s)
        at = dynamic.index(n)
        last = max((dynamic.index(s) for s in sources if s in dynamic), default=-1)
        if last > at:
            dynamic.pop(at)
            dynamic.insert(last, n)


def strongly_connected(nodes: list[str], successors: dict[str, list[str]]) -> list[list[str]]:
    """The strongly connected components of a directed graph (Tarjan's
    algorithm, with an explicit stack: systems may have thousands of
    instances), each emitted after every component it reaches; the nodes
    and their successors are visited in the order given."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []
    for root in nodes:
        if root in index:
            continue
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        work = [(root, iter(successors[root]))]
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(successors[child])))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[node])
            if low[node] == index[node]:
                comp = []
                while True:
                    m = stack.pop()
                    on_stack.discard(m)
                    comp.append(m)
                    if m == node:
                        break
                out.append(comp)
    return out


def loop_name(members: list[str], links: list[Link]) -> str:
    """A loop as a cycle through its first member ("a -> b -> a"), with the
    members it does not pass through named after it."""
    succ: dict[str, list[str]] = {}
    for link in links:
        if link.dst not in succ.setdefault(link.src, []):
            succ[link.src].append(link.dst)
    first = members[0]
    # Breadth first: the shortest way from the first member back to it.
    came_from: dict[str, str] = {}
    frontier = [first]
    while frontier and first not in came_from:
        nxt = []
        for n in frontier:
            for m in succ.get(n, []):
                if m not in came_from:
                    came_from[m] = n
                    nxt.append(m)
        frontier = nxt
    path = [first]
    n = came_from.get(first, first)
    while n != first:
        path.append(n)
        n = came_from[n]
    cycle = [first] + path[:0:-1] + [first]
    rest = [m for m in members if m not in cycle]
    text = " -> ".join(cycle)
    if rest:
        text += f" (with {', '.join(rest)})"
    return text


def _has_free_outputs(inst: Instance) -> bool:
    """True when some output does not depend on inputs (the FMU has dynamics)."""
    return any(
        v.causality == "output" and v.dependencies is not None and len(v.dependencies) == 0
        for v in inst.variables.values()
    )
