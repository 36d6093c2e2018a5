"""The wiring graph: who feeds whom, and in which order outputs are updated.

An instance is *feedthrough-only* when every output the scene connects
depends directly on its inputs (ModelStructure dependencies): the
escapements and the drag. Such instances carry no dynamics the master must
step in a Gauss-Seidel sequence; they are stepped first in a communication
step, while their inputs still hold the values of the step's start, which
is when they commit discrete modes. Outputs are then propagated at the new
communication point in dependency order.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from ..errors import SceneError
from .description import link_shape_problem
from .fmu import Instance
from .names import split_link, split_ref


@dataclass(frozen=True)
class Link:
    """The input receives factor * output + offset (a Real link's linear
    transformation or unit conversion; the identity is never computed)."""

    src: str
    output: str
    dst: str
    input: str
    factor: float = 1.0
    offset: float = 0.0

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


def expand_arrays(instances: dict[str, Instance], links: list[Link]) -> list[Link]:
    """Links between FMI 3.0 arrays as links between their elements, in
    order (arrays of the same shape only); SceneError where shapes differ or
    where an input array would be connected in part (FMI 3.0 sets an array
    whole)."""
    if not any(inst.arrays for inst in instances.values()):
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


def build(instances: dict[str, Instance], links: list[Link], step_order: list[str] | None = None) -> Wiring:
    """The wiring of these links (links between whole arrays become links
    between their elements: ``Wiring.links``)."""
    links = expand_arrays(instances, links)
    feeds: dict[tuple[str, str], bool] = {}
    for link in links:
        var = instances[link.src].variables[link.output]
        # Missing dependency information means "depends on all inputs".
        feeds[(link.src, link.output)] = var.dependencies is None or len(var.dependencies) > 0

    connected_outputs: dict[str, list[str]] = {}
    for link in links:
        connected_outputs.setdefault(link.src, []).append(link.output)
    names = list(instances)
    feedthrough_only = [
        n for n in names
        if n in connected_outputs and all(feeds[(n, o)] for o in connected_outputs[n])
    ]
    feedthrough_only += [n for n in names if n not in connected_outputs and not _has_free_outputs(instances[n])]
    dynamic = [n for n in (step_order or names) if n not in feedthrough_only]

    # Topological order over feedthrough edges only: a source must be
    # evaluated before an output of its destination that depends on it.
    edges = {n: set() for n in names}
    for link in links:
        if feeds[(link.src, link.output)] and link.src != link.dst:
            edges[link.src].add(link.dst)
        elif feeds[(link.src, link.output)]:
            raise SceneError(
                f"algebraic loop: {link.src}.{link.output} feeds {link.dst}.{link.input} of the same instance"
            )
    order: list[str] = []
    state = {n: 0 for n in names}  # 0 new, 1 on stack, 2 done

    def visit(n: str, path: list[str]) -> None:
        if state[n] == 2:
            return
        if state[n] == 1:
            cycle = " -> ".join(path[path.index(n):] + [n])
            raise SceneError(f"algebraic loop through direct-feedthrough outputs: {cycle}")
        state[n] = 1
        for m in sorted(edges[n]):
            visit(m, path + [n])
        state[n] = 2
        order.append(n)

    for n in names:
        visit(n, [])
    order.reverse()
    return Wiring(links, feedthrough_only, dynamic, order, feeds)


def _has_free_outputs(inst: Instance) -> bool:
    """True when some output does not depend on inputs (the FMU has dynamics)."""
    return any(
        v.causality == "output" and v.dependencies is not None and len(v.dependencies) == 0
        for v in inst.variables.values()
    )
