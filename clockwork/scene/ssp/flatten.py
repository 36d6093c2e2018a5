"""The SSP reader's second job: a nested SSD's connections as the links of a
flat system. A chain of connections through system connectors becomes one
link from a component's output to a component's input, with the chain's
linear transformations and unit conversions folded into the link's factor
and offset; a component input fed only by system connectors is left for
parameters.py (the connectors may carry a value).
"""

from __future__ import annotations

from ...fmi.description import types_connect
from ...fmi.description import variables as variables_of
from ...errors import SceneError
from ...numbers import shorten
from .documents import conversion, fmu_units
from .structure import Structure, shown

MAX_PATH_STEPS = 100_000  # edges visited walking upstream from one input: loops of connectors grow as n!


class Aliases:
    """A system connector that passes one component output on unchanged can
    be recorded by its name ("wB", "sub.w"): it records that output. Worked
    out for the names asked (each a walk of the connections), not for every
    connector: a chain of n connectors would cost n walks of n steps."""

    def __init__(self, flat=None, adj=None):
        self._flat, self._adj = flat, adj or {}
        self._nodes = {(f"{n[1]}.{n[2]}" if n[1] else n[2]): n for n in self._adj if n[0] == "s"}
        self._known: dict[str, str | None] = {}

    def get(self, name: str, default=None):
        node = self._nodes.get(name) if isinstance(name, str) else None
        if node is None:
            return default
        if name not in self._known:
            self._known[name] = self._flat.alias(node, self._adj)
        return self._known[name] or default



class Flat:
    """Walks the connections of a `Structure` (its edges between connector
    nodes, ``("c", instance, variable)`` or ``("s", system path, connector)``)."""

    def __init__(self, structure: Structure):
        self.structure = structure
        self.aliases = Aliases()

    def var(self, node: tuple):
        return variables_of(self.structure.instances[node[1]].md)[node[2]]

    def role(self, node: tuple) -> str:
        """source (component output), sink (component input or parameter) or through (a system connector)."""
        if node[0] == "s":
            return "through"
        return "source" if self.var(node).causality == "output" else "sink"

    def unit(self, node: tuple) -> str | None:
        if node[0] == "s":
            return self.structure.systems[node[1]].connectors[node[2]].unit
        return self.structure.instances[node[1]].connectors[node[2]].unit

    def flatten(self):
        """{(instance, input): ((src instance, output), factor, offset)} and
        {(instance, variable): (system path, connector, chain)} for component
        variables fed by a system connector that no output drives; sets
        `aliases`."""
        adj: dict[tuple, list] = {}
        for e in self.structure.edges:
            ra, rb = self.role(e.a), self.role(e.b)
            if ra == rb == "source":
                raise e.doc.fail(e.el, "expected an output connected to an input: both ends are outputs")
            if ra == rb == "sink":
                raise e.doc.fail(e.el, "expected an output connected to an input: both ends are inputs")
            adj.setdefault(e.a, []).append((e, e.b))
            adj.setdefault(e.b, []).append((e, e.a))
        links, fed = {}, {}
        self.aliases = Aliases(self, adj)
        for node in adj:
            if self.role(node) != "sink":
                continue
            found = self.walk(node, adj)
            sources = [f for f in found if f[0][0] == "c"]
            if len(sources) > 1:
                names = " and ".join(shown(f"{s[1]}.{s[2]}") for s, _ in sources[:2])
                e = sources[1][1][-1][0]
                raise e.doc.fail(e.el, f"input {shown(node[1] + '.' + node[2])} is fed by two outputs: {names}")
            if sources:
                src, chain = sources[0]
                if self.var(node).causality != "input":
                    last = chain[-1][0]
                    raise last.doc.fail(last.el, f"expected an input at the end: {shown(node[1] + '.' + node[2])} is a "
                                                 f"{self.var(node).causality}, which an output cannot feed")
                factor, offset = self.chain(chain, self.var(src), self.var(node))
                links[(node[1], node[2])] = ((src[1], src[2]), factor, offset)
            else:
                # fed only by system connectors: they may carry a parameter value
                fed[(node[1], node[2])] = [(s, chain) for s, chain in found]
        return links, fed

    def walk(self, node: tuple, adj: dict) -> list:
        """What feeds `node`: [(source node, [(edge, upstream, downstream)] in data-flow order)],
        a component output, or a system connector with nothing upstream.

        Every simple path from `node` upstream, depth first, on an explicit
        stack with the path's nodes marked and unmarked (a chain of thousands
        of system connectors costs its length, not a recursion as deep),
        bounded by MAX_PATH_STEPS edges visited."""
        found = []
        visits = 0
        on_path = {node}
        # frames: [node, its chain as a linked list (step, rest), its edges, next edge, len(found) on entry]
        stack = [[node, None, adj.get(node, []), 0, 0]]
        while stack:
            frame = stack[-1]
            cur, link, edges, i, before = frame
            while i < len(edges) and edges[i][1] in on_path:
                i += 1
            if i == len(edges):
                stack.pop()
                on_path.discard(cur)
                if stack and len(found) == before:  # a system connector with nothing upstream
                    found.append((cur, _unlink(link)))
                continue
            frame[3] = i + 1
            e, other = edges[i]
            visits += 1
            if visits > MAX_PATH_STEPS:  # loops of system connectors: the paths grow as n!
                raise e.doc.fail(e.el, f"more than {MAX_PATH_STEPS:,} paths through system connectors lead to "
                                       f"{shorten('.'.join(n for n in node[1:] if n), 200)}: expected connections "
                                       "without loops")
            role = self.role(other)
            step = ((e, other, cur), link)
            if role == "source":
                found.append((other, _unlink(step)))
            elif role == "through":
                on_path.add(other)
                stack.append([other, step, adj.get(other, []), 0, len(found)])
        return found

    def alias(self, node: tuple, adj: dict) -> str | None:
        """The "instance.output" a system connector passes on unchanged, or None."""
        sources = [f for f in self.walk(node, adj) if f[0][0] == "c"]
        if len(sources) != 1:
            return None
        src, chain = sources[0]
        try:
            var = self.var(src)
            if self.chain(chain, var, var) != (1.0, 0.0):
                return None
        except SceneError:
            return None
        return f"{src[1]}.{src[2]}"

    def chain(self, chain, src_var, dst_var) -> tuple[float, float]:
        """The factor and offset of a chain of connections in data-flow order."""
        if src_var is not None and not types_connect(src_var.type, dst_var.type):
            e = chain[-1][0]
            raise e.doc.fail(e.el, f"type mismatch: the source is {src_var.type}, the input {dst_var.type}")
        factor, offset = 1.0, 0.0
        for e, up, down in chain:
            f, o = 1.0, 0.0
            if not e.suppress:
                tables = [self.structure.units] + [fmu_units(self.structure.instances[n[1]].md)
                                                   for n in (up, down) if n[0] == "c"]
                conv = conversion(self.unit(up), self.unit(down), *tables)
                if isinstance(conv, str):
                    raise e.doc.fail(e.el, f"expected convertible units: {conv}")
                f, o = conv
            if (e.factor, e.offset) != (1.0, 0.0):
                if dst_var.type != "Real":
                    raise e.doc.fail(e.el, f"a linear transformation needs Real connectors, not {dst_var.type}")
                f, o = e.factor * f, e.factor * o + e.offset
            factor, offset = f * factor, f * offset + o
        return factor, offset


def _unlink(link) -> list:
    """A chain kept as a linked list (step, rest), newest step first, as a list."""
    out = []
    while link is not None:
        out.append(link[0])
        link = link[1]
    return out
