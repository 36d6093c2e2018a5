"""Read an SSP archive (.ssp) or a System Structure Description (.ssd) into
the scene model: the same components and connections a TOML scene gives.

What is read (SSP 1.0 and 2.0; docs/scenes.md, "SSP and SSD files"):

- ``ssd:Component`` FMUs, inside the archive or beside the SSD (source URIs
  relative to the SSD);
- nested ``ssd:System`` elements, flattened: an instance is named by the
  path of its systems below the top-level one, joined with "." (``sub.comp``);
  a chain of connections through system connectors becomes one link from a
  component's output to a component's input;
- ``ssd:Connection`` with ``ssc:LinearTransformation`` and unit conversion
  between the connectors' units (``ssd:Units``, else the FMU's unit
  definitions), both folded into the link's factor and offset;
- ``ssd:ParameterBinding`` at component and system level, inline
  (``ssd:ParameterValues``) or from ``.ssv`` files, with ``.ssm`` parameter
  mappings (names, linear transformations, units), with the SSP rules of
  precedence (a later binding over an earlier one, a system's over its
  elements') and of hierarchical names and prefixes; system connectors
  given a value pass it on to the component inputs and parameters they feed;
- ``ssd:DefaultExperiment`` (start, stop), the step of OMSimulator's
  annotation (``oms:FixedStepMaster``) and clockwork's own annotation
  (``clockwork export-ssp`` writes the master settings and the record list).

Everything else that would change the simulation is refused with one line
naming the file, the element and what was expected: signal dictionaries,
components that reference other SSDs, Model-Exchange-only FMUs, array
connectors, mapping transformations other than linear ones.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ...engine.description import FmuError, read_fmu, types_connect, var_unit
from ...engine.description import variables as variables_of
from ...engine.model_exchange import interface_of, model_exchange_problem
from ...engine.settings import SETTINGS as _MASTER_SETTINGS
from ...errors import SceneError
from ...files import absent
from ...hashing import sha256_file
from ...numbers import parse_int, parse_real, shorten
from ..checks import SETTABLE, STRUCTURAL, Ctx, convert_value, instance_problem, settable_problem
from ..model import Component, Connection
from .common import CW_ANNOTATION, CW_NS, NS, OMS_NS, OSP_ANNOTATION, OSP_NS, VERSIONS, q
from .documents import SSD_NAME, Doc, Store, boolean, conversion, fmu_units, number, tag_name, unit_table

FMU_TYPE = "application/x-fmu-sharedlibrary"
PSET_TYPE = "application/x-ssp-parameter-set"
PMAP_TYPE = "application/x-ssp-parameter-mapping"
_REALS = ("Real", "Float64", "Float32")
_INTEGERS = ("Integer", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64")
_TYPES = _REALS + _INTEGERS + ("Boolean", "String", "Enumeration")
_FMI_TYPE = {**{t: "Real" for t in _REALS}, **{t: "Integer" for t in _INTEGERS},
             "Boolean": "Boolean", "String": "String", "Enumeration": "Enumeration"}
# What clockwork's annotation may set: MasterSettings' fields and record keys.
_RECORD_KEYS = ("interval", "ticks")
# Bounds before the work: each component is an FMU instance (a clock has 2 to 6),
# and each input's sources are found by walking the connections.
MAX_COMPONENTS = 10_000  # validate and run grow linearly: docs/benchmarks.md, "Systems of many FMUs"
MAX_PATH_STEPS = 100_000
_MASTER_FIELDS = tuple(_MASTER_SETTINGS)
# Warnings of one kind beyond this many are counted, not printed.
WARNINGS_SHOWN = 3
# What the SSP may hold around a connection's or mapping entry's transformation
# without changing the simulation (the drawing, tools' annotations).
_INERT = {q("ssd", "ConnectionGeometry"), q("ssd", "Annotations"), q("ssc", "Annotations")}


class Aliases:
    """A system connector that passes one component output on unchanged can
    be recorded by its name ("wB", "sub.w"): it records that output. Worked
    out for the names asked (each a walk of the connections), not for every
    connector: a chain of n connectors would cost n walks of n steps."""

    def __init__(self, reader=None, adj=None):
        self._reader, self._adj = reader, adj or {}
        self._nodes = {(f"{n[1]}.{n[2]}" if n[1] else n[2]): n for n in self._adj if n[0] == "s"}
        self._known: dict[str, str | None] = {}

    def get(self, name: str, default=None):
        node = self._nodes.get(name) if isinstance(name, str) else None
        if node is None:
            return default
        if name not in self._known:
            self._known[name] = self._reader._alias(node, self._adj)
        return self._known[name] or default


@dataclass
class SspScene:
    """What an SSP says, flattened; load.py makes the Scene of it."""

    name: str
    description: str
    components: dict[str, Component]
    connections: tuple[Connection, ...]
    sections: dict  # "experiment", "master", "record" tables, as a TOML scene would hold them
    sha256: str  # of the archive; of an .ssd and the .ssv/.ssm files it reads
    warnings: list[str] = field(default_factory=list)
    aliases: Aliases = field(default_factory=Aliases)  # system connector -> "instance.output" it passes on
    # osp:StepSizeHint of components: instance -> (step in s, file, key); load.py decides after --set
    step_hints: dict[str, tuple[float, str, str]] = field(default_factory=dict)
    # where the SSD gives no stopTime: (file, key) for the note that 1 s is taken
    no_stop: tuple[str, str] | None = None
    # where a section's value came from: dotted key ("master.step") -> (file, key), so that a value
    # refused later is named by its own origin (an osp:FixedStepAlgorithm's baseStepSize, a DefaultExperiment's)
    labels: dict[str, tuple[str, str]] = field(default_factory=dict)


# ---------------------------------------------------------------- structure


@dataclass
class _Connector:
    name: str
    kind: str
    type: str | None  # FMI type name from the ssc type element, None if not given
    unit: str | None
    el: object


@dataclass
class _Element:
    name: str  # as in the SSD
    path: str  # hierarchical: "" for the top-level system, "sub", "sub.comp"
    is_system: bool
    doc: Doc
    el: object
    connectors: dict[str, _Connector]
    children: dict[str, "_Element"] = field(default_factory=dict)
    fmu_path: Path | None = None
    fmu_label: str = ""  # an archive's FMU as messages name it (archive/member); "": its path
    interface: str | None = None  # "model-exchange" or "co-simulation" as implementation= asks; None: any
    md: object = None
    digest: str = ""
    indicators: tuple = ()
    connections: list = field(default_factory=list)


@dataclass
class _Edge:
    a: tuple  # ("c", instance, variable) or ("s", system path, connector)
    b: tuple
    factor: float
    offset: float
    suppress: bool
    doc: Doc
    el: object


class _Reader:
    def __init__(self, path: Path):
        self.path = path
        self.store = Store(path)
        self.warnings: list[str] = []
        self.units: dict[str, Unit] = {}
        self.instances: dict[str, _Element] = {}
        self.systems: dict[str, _Element] = {}
        self.edges: list[_Edge] = []
        self.step_hints: dict[str, tuple[float, str, str]] = {}
        self.labels: dict[str, tuple[str, str]] = {}  # SspScene.labels
        self._warned: dict[str, list[str]] = {}  # kind -> its warnings, in order

    def warn(self, label: str, key: str, text: str, kind: str | None = None) -> None:
        """A warning line; of each `kind` (what the lines are about, for the
        count), the first WARNINGS_SHOWN are kept and the rest counted."""
        self._warned.setdefault(kind or text, []).append(f"{label}: {key}: {text}")

    def _summarised_warnings(self) -> list[str]:
        out = []
        for kind, lines in self._warned.items():
            out += lines[:WARNINGS_SHOWN]
            if len(lines) > WARNINGS_SHOWN:
                out.append(f"... and {len(lines) - WARNINGS_SHOWN:,} more like the last: {kind}")
        return out

    # -- reading

    def read(self) -> SspScene:
        if self.store.zip is not None:
            where: str | Path = SSD_NAME
        else:
            where = self.path
        doc = self.store.doc(where, "ssd:SystemStructureDescription")
        root = doc.root
        version = root.get("version")
        if version not in VERSIONS:
            raise doc.fail(root, f"expected the SSP version {' or '.join(VERSIONS)}", "version")
        self.units = unit_table(doc, root.find(q("ssd", "Units")))
        system = root.find(q("ssd", "System"))
        if system is None:
            raise doc.fail(root, "expected an ssd:System element")
        top = self._system(doc, system, "")
        if not self.instances:
            raise doc.fail(system, "expected at least one ssd:Component (an FMU) in the system or its sub-systems")
        self._connections(top)
        links, fed = self._flatten()
        values = self._bindings(top)
        components = self._components(values, fed)
        connections = []
        for (inst, var), (src, factor, offset) in links.items():
            connections.append(Connection(src[0], src[1], inst, var, factor, offset))
        experiment, osp_step = self._experiment(doc, root)
        sections = {"experiment": experiment, "master": self._master(doc, system, osp_step),
                    "record": self._record(doc, system)}
        if "outputs" not in sections["record"]:
            sections["record"]["outputs"] = self._default_record()
        if self.store.zip is not None:
            digest = sha256_file(self.path)  # streamed: an archive may be large
        else:
            digest = self.store.digest.hexdigest()
        no_stop = None
        if "stop" not in experiment:
            exp = root.find(q("ssd", "DefaultExperiment"))
            no_stop = (doc.label, doc.key(exp if exp is not None else root))
        self.warnings = self._summarised_warnings()
        return SspScene(root.get("name") or self.path.stem, system.get("description") or "", components,
                        tuple(connections), sections, digest, self.warnings, self.aliases, self.step_hints,
                        no_stop, self.labels)

    def _connectors(self, doc: Doc, el, md=None) -> dict[str, _Connector]:
        out: dict[str, _Connector] = {}
        holder = el.find(q("ssd", "Connectors"))
        if holder is None:
            return out
        variables = variables_of(md) if md is not None else None
        for c in holder.iterfind(q("ssd", "Connector")):
            name = c.get("name")
            if not name:
                raise doc.fail(c, "expected a connector name", "name")
            if name in out:
                raise doc.fail(c, "expected a unique connector name: this one is declared twice", "name")
            kind = c.get("kind")
            if kind not in ("input", "output", "parameter", "calculatedParameter", "structuralParameter",
                            "constant", "local", "inout", "unspecified"):
                raise doc.fail(c, "expected a kind: input, output, parameter, calculatedParameter, ...", "kind")
            ctype, unit = None, None
            for child in c:
                ns, _, local = child.tag[1:].partition("}")
                if ns == NS["ssc"] and (local in _TYPES or local == "Binary"):  # Binary: FMI 3.0's
                    ctype = _FMI_TYPE.get(local, local)
                    unit = (child.get("unit") or None) if ctype == "Real" else None  # unit="" is no unit
                elif ns == NS["ssc"] and local == "Clock":
                    raise doc.fail(child, "not supported: Clock connectors")
            if c.find(q("ssc", "Dimension")) is not None or c.find(q("ssd", "Dimension")) is not None:
                raise doc.fail(c, "not supported: array connectors (ssc:Dimension)")
            if variables is not None:
                v = variables.get(name)
                if v is None:
                    raise doc.fail(c, f"expected the name of a variable of {md.modelName}: it has no {_s(name)}",
                                   "name")
                if ctype is not None and ctype != _FMI_TYPE.get(v.type, v.type) and not (
                        ctype == "Integer" and v.type == "Enumeration"):
                    raise doc.fail(c, f"type mismatch: the connector is {ctype}, {md.modelName}.{name} is {v.type}")
                if kind in ("input", "output") and v.causality != kind:
                    raise doc.fail(c, f"expected kind={v.causality!r}: {md.modelName}.{name} is "
                                      f"{'an' if v.causality[0] in 'aeiou' else 'a'} {v.causality}", "kind")
                if v.type == "Real" and var_unit(v) is not None:
                    # the FMU's unit is what its numbers are in
                    if unit is not None and conversion(unit, var_unit(v), self.units, fmu_units(md)) != (1.0, 0.0):
                        self.warn(doc.label, doc.key(c, "name"), f"the connector is in {shorten(unit, 100)}, "
                                  f"{md.modelName}.{name} in {var_unit(v)}; the FMU's unit is used",
                                  "connector units that differ from the FMU's (the FMU's is used)")
                    unit = var_unit(v)
                ctype = v.type
            out[name] = _Connector(name, kind, ctype, unit, c)
        return out

    def _system(self, doc: Doc, el, path: str) -> _Element:
        """The system and its elements, depth first in document order (the
        instances in that order), on an explicit stack, not by recursion."""
        top = self._new_system(doc, el, path)
        stack = [(top, iter(self._elements(doc, el)))]
        while stack:
            node, children = stack[-1]
            child = next(children, None)
            if child is None:
                stack.pop()
                continue
            ns, _, local = child.tag[1:].partition("}")
            name = child.get("name")
            if ns != NS["ssd"] or local not in ("Component", "System"):
                what = "signal dictionary references" if local == "SignalDictionaryReference" else f"{local} elements"
                raise doc.fail(child, f"not supported: {shorten(what, 100)}; expected ssd:Component or ssd:System")
            if not name:
                raise doc.fail(child, "expected a non-empty element name", "name")
            problem = instance_problem(name)
            if problem:
                # an element's name becomes (part of) an instance name: the same rule as a scene's
                raise doc.fail(child, problem.replace("instance name", "element name"), "name")
            if name in node.children:
                raise doc.fail(child, f"expected a unique element name in system {shorten(node.name, 100)!r}", "name")
            sub = f"{node.path}.{name}" if node.path else name
            if local == "System":
                node.children[name] = self._new_system(doc, child, sub)
                stack.append((node.children[name], iter(self._elements(doc, child))))
            else:
                node.children[name] = self._component(doc, child, sub)
        return top

    def _new_system(self, doc: Doc, el, path: str) -> _Element:
        node = _Element(el.get("name") or "", path, True, doc, el, self._connectors(doc, el))
        self.systems[path] = node
        if el.find(q("ssd", "SignalDictionaries")) is not None:
            raise doc.fail(el.find(q("ssd", "SignalDictionaries")), "not supported: signal dictionaries")
        return node

    @staticmethod
    def _elements(doc: Doc, el) -> list:
        elements = el.find(q("ssd", "Elements"))
        return list(elements) if elements is not None else []

    def _component(self, doc: Doc, el, path: str) -> _Element:
        ctype = el.get("type", FMU_TYPE)
        if ctype in ("application/x-ssp-definition", "application/x-ssp-package"):
            raise doc.fail(el, "not supported: a component that references another SSD or SSP; "
                               f"expected {FMU_TYPE}", "type")
        if ctype != FMU_TYPE:
            raise doc.fail(el, f"expected type {FMU_TYPE} (an FMU)", "type")
        if el.get("source") is None:
            raise doc.fail(el, "missing required attribute; expected the FMU's path", "source")
        if len(self.instances) >= MAX_COMPONENTS:
            raise doc.fail(el, f"more than {MAX_COMPONENTS} components (FMU instances) in the system and its "
                               "sub-systems: not read")
        where = self.store.resolve(doc, el, "source")
        fmu = self.store.fmu(where)
        label = self.store.label(where) if self.store.zip is not None else None  # None: its own path
        try:
            md, digest, indicators = read_fmu(fmu, label=label)
        except FmuError as e:
            raise doc.fail(el, str(e), "source") from None
        impl = el.get("implementation", "any")
        if impl == "ScheduledExecution":
            raise doc.fail(el, "expected any or CoSimulation: scheduled execution is FMI 3.0", "implementation")
        interface = {"ModelExchange": "model-exchange", "CoSimulation": "co-simulation"}.get(impl)
        if interface is not None or md.coSimulation is None:
            try:
                if interface_of(md, interface) == "model-exchange":
                    indicators = ()  # the FMU's own event indicators are located inside its wrapper
                    problem = model_exchange_problem(md)
                    if problem:
                        raise SceneError(problem)
            except SceneError as e:
                raise doc.fail(el, e.detail, "implementation" if interface else "source") from None
        node = _Element(el.get("name"), path, False, doc, el, self._connectors(doc, el, md))
        node.fmu_path, node.md, node.digest, node.indicators = fmu, md, digest, indicators
        node.fmu_label = label or ""
        node.interface = interface
        hint = self._step_hint(doc, el)
        if hint is not None:
            self.step_hints[path] = hint
        if path in self.instances:
            raise doc.fail(el, f"expected a unique instance name: {_s(path)} names two components once systems "
                               "are flattened", "name")
        self.instances[path] = node
        return node

    def _end(self, system: _Element, doc: Doc, el, which: str) -> tuple[tuple, _Connector]:
        # an empty element name (OMSimulator writes one) is the system's own connector
        elem_name, conn_name = el.get(f"{which}Element") or None, el.get(f"{which}Connector")
        if conn_name is None:
            raise doc.fail(el, "missing required attribute", f"{which}Connector")
        if elem_name is None:
            c = system.connectors.get(conn_name)
            if c is None:
                raise doc.fail(el, f"system {_s(system.name)!r} has no connector {_s(conn_name)!r}; connectors: "
                                   f"{_s(', '.join(system.connectors) or 'none')}", f"{which}Connector")
            return ("s", system.path, conn_name), c
        target = system.children.get(elem_name)
        if target is None:
            raise doc.fail(el, f"system {_s(system.name)!r} has no element {_s(elem_name)!r}; elements: "
                               f"{_s(', '.join(system.children) or 'none')}", f"{which}Element")
        c = target.connectors.get(conn_name)
        if c is None:
            raise doc.fail(el, f"{_s(elem_name)} has no connector {_s(conn_name)!r}; connectors: "
                               f"{_s(', '.join(target.connectors) or 'none')}", f"{which}Connector")
        return (("s" if target.is_system else "c"), target.path, conn_name), c

    def _connections(self, top: _Element) -> None:
        todo = [top]  # systems, depth first in document order (a stack, not recursion)
        while todo:
            system = todo.pop()
            self._system_connections(system)
            todo += reversed([c for c in system.children.values() if c.is_system])

    def _system_connections(self, system: _Element) -> None:
        doc = system.doc
        holder = system.el.find(q("ssd", "Connections"))
        for el in (holder if holder is not None else []):
            if el.tag != q("ssd", "Connection"):
                raise doc.fail(el, "expected ssd:Connection elements only")
            for attr in ("startIndices", "endIndices"):
                if el.get(attr) is not None:
                    raise doc.fail(el, "not supported: connections of array elements", attr)
            a, _ = self._end(system, doc, el, "start")
            b, _ = self._end(system, doc, el, "end")
            factor, offset = _transformation(doc, el, "connections")
            self.edges.append(_Edge(a, b, factor, offset, boolean(doc, el, "suppressUnitConversion"), doc, el))

    # -- flattening

    def _var(self, node: tuple):
        return variables_of(self.instances[node[1]].md)[node[2]]

    def _role(self, node: tuple) -> str:
        """source (component output), sink (component input or parameter) or through (a system connector)."""
        if node[0] == "s":
            return "through"
        return "source" if self._var(node).causality == "output" else "sink"

    def _unit(self, node: tuple) -> str | None:
        if node[0] == "s":
            return self.systems[node[1]].connectors[node[2]].unit
        return self.instances[node[1]].connectors[node[2]].unit

    def _flatten(self):
        """{(instance, input): ((src instance, output), factor, offset)} and
        {(instance, variable): (system path, connector, chain)} for component
        variables fed by a system connector that no output drives."""
        adj: dict[tuple, list] = {}
        for e in self.edges:
            ra, rb = self._role(e.a), self._role(e.b)
            if ra == rb == "source":
                raise e.doc.fail(e.el, "expected an output connected to an input: both ends are outputs")
            if ra == rb == "sink":
                raise e.doc.fail(e.el, "expected an output connected to an input: both ends are inputs")
            adj.setdefault(e.a, []).append((e, e.b))
            adj.setdefault(e.b, []).append((e, e.a))
        links, fed = {}, {}
        self.aliases = Aliases(self, adj)
        for node in adj:
            if self._role(node) != "sink":
                continue
            found = self._walk(node, adj)
            sources = [f for f in found if f[0][0] == "c"]
            if len(sources) > 1:
                names = " and ".join(_s(f"{s[1]}.{s[2]}") for s, _ in sources[:2])
                e = sources[1][1][-1][0]
                raise e.doc.fail(e.el, f"input {_s(node[1] + '.' + node[2])} is fed by two outputs: {names}")
            if sources:
                src, chain = sources[0]
                if self._var(node).causality != "input":
                    last = chain[-1][0]
                    raise last.doc.fail(last.el, f"expected an input at the end: {_s(node[1] + '.' + node[2])} is a "
                                                 f"{self._var(node).causality}, which an output cannot feed")
                factor, offset = self._chain(chain, self._var(src), self._var(node))
                links[(node[1], node[2])] = ((src[1], src[2]), factor, offset)
            else:
                # fed only by system connectors: they may carry a parameter value
                fed[(node[1], node[2])] = [(s, chain) for s, chain in found]
        return links, fed

    def _walk(self, node: tuple, adj: dict) -> list:
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
            role = self._role(other)
            step = ((e, other, cur), link)
            if role == "source":
                found.append((other, _unlink(step)))
            elif role == "through":
                on_path.add(other)
                stack.append([other, step, adj.get(other, []), 0, len(found)])
        return found

    def _alias(self, node: tuple, adj: dict) -> str | None:
        """The "instance.output" a system connector passes on unchanged, or None."""
        sources = [f for f in self._walk(node, adj) if f[0][0] == "c"]
        if len(sources) != 1:
            return None
        src, chain = sources[0]
        try:
            var = self._var(src)
            if self._chain(chain, var, var) != (1.0, 0.0):
                return None
        except SceneError:
            return None
        return f"{src[1]}.{src[2]}"

    def _chain(self, chain, src_var, dst_var) -> tuple[float, float]:
        """The factor and offset of a chain of connections in data-flow order."""
        if src_var is not None and not types_connect(src_var.type, dst_var.type):
            e = chain[-1][0]
            raise e.doc.fail(e.el, f"type mismatch: the source is {src_var.type}, the input {dst_var.type}")
        factor, offset = 1.0, 0.0
        for e, up, down in chain:
            f, o = 1.0, 0.0
            if not e.suppress:
                tables = [self.units] + [fmu_units(self.instances[n[1]].md) for n in (up, down) if n[0] == "c"]
                conv = conversion(self._unit(up), self._unit(down), *tables)
                if isinstance(conv, str):
                    raise e.doc.fail(e.el, f"expected convertible units: {conv}")
                f, o = conv
            if (e.factor, e.offset) != (1.0, 0.0):
                if dst_var.type != "Real":
                    raise e.doc.fail(e.el, f"a linear transformation needs Real connectors, not {dst_var.type}")
                f, o = e.factor * f, e.factor * o + e.offset
            factor, offset = f * factor, f * offset + o
        return factor, offset

    # -- parameters

    def _bindings(self, top: _Element) -> dict[tuple, tuple]:
        """{node: (value, type, unit, label, key)}, the SSP's precedence applied:
        an element's bindings before its system's, so that the system's win.
        Depth first in document order, on a stack (not recursion)."""
        values: dict[tuple, tuple] = {}
        stack = [(top, iter(top.children.values()))]
        while stack:
            system, children = stack[-1]
            child = next(children, None)
            if child is None:
                stack.pop()
                for name, v in self._element_values(system):
                    self._assign(system, name, v, values, exact=False)
            elif child.is_system:
                stack.append((child, iter(child.children.values())))
            else:
                for name, v in self._element_values(child):
                    self._assign(child, name, v, values, exact=True)
        return values

    def _assign(self, elem: _Element, name: str, v: tuple, values: dict, exact: bool) -> None:
        targets = [("c", elem.path, name)] if not elem.is_system else self._resolve(elem, name)
        if not elem.is_system and name not in variables_of(elem.md):
            targets = []
        if not targets:
            self.warn(v[3], v[4], f"{shorten(name, 100)} names no variable of {elem.path or elem.name!r}; ignored "
                                  "(SSP: a parameter value without a match is not applied)",
                      "parameter values that name no variable (not applied)")
        for t in targets:
            values[t] = v

    def _resolve(self, system: _Element, name: str) -> list[tuple]:
        """Every variable a hierarchical name reaches in a system (SSP allows punning)."""
        out = []
        todo = [(system, name)]
        while todo:
            system, name = todo.pop()
            if name in system.connectors:
                out.append(("s", system.path, name))
            for ename, child in system.children.items():
                if name.startswith(ename + "."):
                    rest = name[len(ename) + 1:]
                    if child.is_system:
                        todo.append((child, rest))
                    elif rest in variables_of(child.md):
                        out.append(("c", child.path, rest))
        return out

    def _element_values(self, elem: _Element) -> list[tuple[str, tuple]]:
        """(name, (value, type, unit, label, key)) of an element's bindings, in order."""
        doc = elem.doc
        holder = elem.el.find(q("ssd", "ParameterBindings"))
        out = []
        for b in (holder if holder is not None else []):
            if b.tag != q("ssd", "ParameterBinding"):
                raise doc.fail(b, "expected ssd:ParameterBinding elements only")
            if b.get("type", PSET_TYPE) != PSET_TYPE:
                raise doc.fail(b, f"expected type {PSET_TYPE}", "type")
            if b.get("sourceBase", "SSD") != "SSD":
                raise doc.fail(b, "not supported: a parameter source inside the component; expected SSD",
                               "sourceBase")
            inline = b.find(q("ssd", "ParameterValues"))
            if b.get("source") is not None:
                if inline is not None:
                    raise doc.fail(b, "expected either a source or ssd:ParameterValues, not both", "source")
                sdoc = self.store.doc(self.store.resolve(doc, b, "source"), "ssv:ParameterSet")
                pset = sdoc.root
            else:
                pset = inline.find(q("ssv", "ParameterSet")) if inline is not None else None
                if pset is None:
                    raise doc.fail(b, "expected a source or an ssd:ParameterValues with an ssv:ParameterSet")
                sdoc = doc
            params = self._parameter_set(sdoc, pset)
            mapping = b.find(q("ssd", "ParameterMapping"))
            if mapping is not None:
                params = self._mapped(doc, mapping, params, elem)
            prefix = b.get("prefix") or ""
            out += [(prefix + name, v) for name, v in params]
        return out

    def _parameter_set(self, doc: Doc, pset) -> list[tuple[str, tuple]]:
        if pset.get("version") is not None and pset.get("version") not in VERSIONS:
            raise doc.fail(pset, f"expected the SSP version {' or '.join(VERSIONS)}", "version")
        units = {**self.units, **unit_table(doc, pset.find(q("ssv", "Units")))}
        out = []
        seen: dict[str, object] = {}
        holder = pset.find(q("ssv", "Parameters"))
        for p in (holder if holder is not None else []):
            if p.tag != q("ssv", "Parameter"):
                raise doc.fail(p, "expected ssv:Parameter elements only")
            name = p.get("name")
            if not name:
                raise doc.fail(p, "expected a parameter name", "name")
            if name in seen:
                if _same_value(seen[name], p):
                    continue  # said twice alike: nothing to choose
                raise doc.fail(p, f"expected each parameter once in a parameter set: line {seen[name].sourceline} "
                                  "gives it another value (which one is meant is not said)", "name")
            seen[name] = p
            typed = [c for c in p if c.tag.startswith("{" + NS["ssv"] + "}")]
            typed = [c for c in typed if c.tag.partition("}")[2] not in ("Annotations",)]
            if len(typed) != 1:
                raise doc.fail(p, "expected one value element (ssv:Real, ssv:Integer, ssv:Boolean, ...)")
            t = typed[0]
            local = t.tag.partition("}")[2]
            if local not in _TYPES:
                raise doc.fail(t, f"not supported: {_s(local)} parameters; expected Real, Integer, Boolean, String "
                                  "or Enumeration")
            text = t.get("value")
            if text is None:
                raise doc.fail(t, "missing required attribute", "value")
            kind = _FMI_TYPE[local]
            if kind == "Real":
                value: object = number(doc, t, "value")
            elif kind == "Integer":
                try:
                    value = parse_int(text)
                except ValueError:
                    raise doc.fail(t, "expected an integer", "value") from None
            elif kind == "Boolean":
                value = boolean(doc, t, "value")
            else:
                value = text
            # a unit without a definition is refused where it needs converting (conversion)
            unit = (t.get("unit") or None) if kind == "Real" else None
            out.append((name, (value, kind, unit, doc.label, doc.key(p), units)))
        return out

    def _mapped(self, doc: Doc, mapping, params, elem) -> list[tuple[str, tuple]]:
        if mapping.get("type", PMAP_TYPE) != PMAP_TYPE:
            raise doc.fail(mapping, f"expected type {PMAP_TYPE}", "type")
        if mapping.get("sourceBase", "SSD") != "SSD":
            raise doc.fail(mapping, "not supported: a mapping inside the component; expected SSD", "sourceBase")
        if mapping.get("source") is not None:
            mdoc = self.store.doc(self.store.resolve(doc, mapping, "source"), "ssm:ParameterMapping")
            root = mdoc.root
        else:
            mdoc, root = doc, mapping.find(q("ssm", "ParameterMapping"))
            if root is None:
                raise doc.fail(mapping, "expected a source or an inline ssm:ParameterMapping")
        by_name = dict(params)
        out = []
        targets: dict[str, object] = {}
        for m in root:
            if m.tag != q("ssm", "MappingEntry"):
                if m.tag == q("ssc", "Annotations"):
                    continue
                raise mdoc.fail(m, "expected ssm:MappingEntry elements only")
            src, target = m.get("source"), m.get("target")
            if src is None or not target:
                raise mdoc.fail(m, "expected the attributes source and target", "source" if src is None else "target")
            if src not in by_name:
                # An empty source is valid by the schema and names no parameter (OMSimulator writes such entries).
                what = "an empty source names no parameter" if not src else f"the parameter set has no {_s(src)}"
                self.warn(mdoc.label, mdoc.key(m, "source"), f"{what}; entry not applied",
                          "mapping entries whose source names no parameter (not applied)")
                continue
            if target in targets:  # of the entries applied
                raise mdoc.fail(m, f"expected each target once in a parameter mapping: line "
                                   f"{targets[target].sourceline} maps to it too (which value is meant is not said)",
                                "target")
            targets[target] = m
            value, kind, unit, label, key, units = by_name[src]
            suppress = boolean(mdoc, m, "suppressUnitConversion")
            transform = _transformation(mdoc, m, "parameter mapping entries")  # refuses any other kind
            if m.find(q("ssc", "LinearTransformation")) is None:
                transform = None
            if transform is not None:
                if kind != "Real":
                    raise mdoc.fail(m, f"a linear transformation needs a Real parameter, not {kind}")
                # Units convert first (unless suppressed), then the transformation (SSP 2.0, 7.x).
                out.append((target, (value, kind, None if suppress else unit, mdoc.label, mdoc.key(m),
                                     units, transform)))
            else:
                out.append((target, (value, kind, None if suppress else unit, mdoc.label, mdoc.key(m), units)))
        return out

    def _components(self, values: dict, fed: dict) -> dict[str, Component]:
        params: dict[str, dict] = {inst: {} for inst in self.instances}
        linked = set()
        for e in self.edges:
            for n in (e.a, e.b):
                if n[0] == "c" and self._role(n) == "sink":
                    linked.add((n[1], n[2]))
        # values of system connectors reach the variables they feed
        for (inst, var), sources in fed.items():
            for snode, chain in sources:
                if snode in values:
                    v = values[snode]
                    factor, offset = self._chain(chain, None, self._var(("c", inst, var)))
                    if (factor, offset) != (1.0, 0.0) and v[1] == "Real":
                        # in the system connector's unit, then through the connections
                        x = factor * self._real(v, self._unit(snode), ()) + offset
                        v = (x, "Real", None, v[3], v[4], v[5])
                    values.setdefault(("c", inst, var), v)
                    linked.discard((inst, var))
        for node, v in values.items():
            if node[0] != "c":
                continue
            inst, var = node[1], node[2]
            elem = self.instances[inst]
            variable = variables_of(elem.md)[var]
            label, key = v[3], v[4]
            if variable.causality == "structuralParameter":
                raise SceneError(f"{elem.md.modelName}.{_s(var)} {STRUCTURAL}", label, key)
            problem = settable_problem(variable)
            if problem:
                raise SceneError(f"expected {SETTABLE}: {elem.md.modelName}.{_s(var)} is "
                                 f"{'an' if variable.causality[0] in 'aeiou' else 'a'} {variable.causality} "
                                 f"({problem})", label, key)
            if (inst, var) in linked and variable.causality == "input":
                self.warn(label, key, f"{_s(inst + '.' + var)} is a connected input; its connection wins over this "
                                      "value",
                          "values for connected inputs (the connection wins)")
                continue
            params[inst][var] = self._value(v, variable, elem, label, key)
        out = {}
        for inst, elem in self.instances.items():
            out[inst] = Component(inst, elem.fmu_path, elem.digest, elem.md, params[inst], elem.indicators,
                                  interface=elem.interface, fmu_label=elem.fmu_label)
        return out

    def _value(self, v: tuple, variable, elem: _Element, label: str, key: str):
        value, kind, unit = v[0], v[1], v[2]
        ctx = Ctx(Path(label), {})
        if kind != _FMI_TYPE.get(variable.type, variable.type) and not (
                kind == "Integer" and variable.type == "Enumeration") and not (
                kind == "Enumeration" and variable.type == "Enumeration"):
            raise SceneError(f"type mismatch: the value is {kind}, {elem.md.modelName}.{variable.name} is "
                             f"{variable.type}", label, key)
        if kind == "Enumeration":
            items = {i.name: int(i.value) for i in (variable.declaredType.items if variable.declaredType else [])}
            if value not in items:
                raise SceneError(f"expected an item of {variable.name}'s enumeration: {', '.join(items)}",
                                 label, key)
            value = items[value]
        if kind == "Real":
            value = self._real(v, var_unit(variable), (fmu_units(elem.md),))
        return convert_value(ctx, f"{key} ({elem.path}.{variable.name})", value, variable, elem.md)

    def _real(self, v: tuple, unit: str | None, tables: tuple) -> float:
        """A Real parameter value in `unit`, then through its mapping's linear transformation."""
        value = v[0]
        conv = conversion(v[2], unit, v[5], self.units, *tables)
        if isinstance(conv, str):
            raise SceneError(f"expected convertible units: {conv}", v[3], v[4])
        if conv != (1.0, 0.0):
            value = conv[0] * value + conv[1]
        if len(v) > 6:
            value = v[6][0] * value + v[6][1]
        return value

    # -- settings

    def _experiment(self, doc: Doc, root) -> tuple[dict, tuple | None]:
        """The experiment section, and the OSP annotation's base step as
        (step in s, element) or None."""
        exp = root.find(q("ssd", "DefaultExperiment"))
        out = {}
        if exp is None:
            return out, None
        for key, attr in (("start", "startTime"), ("stop", "stopTime")):
            if exp.get(attr) is not None:
                out[key] = number(doc, exp, attr)
                self.labels[f"experiment.{key}"] = (doc.label, doc.key(exp, attr))
        step = None
        osp = self._annotation(doc, exp, OSP_ANNOTATION)
        if osp is not None:
            algorithms = [c for c in osp if c.tag == q("osp", "Algorithm")]
            for c in osp:
                if c.tag != q("osp", "Algorithm"):
                    raise doc.fail(c, f"not supported in the OSP annotation of the experiment: {tag_name(c)}; "
                                      "expected osp:Algorithm")
            if len(algorithms) > 1:
                raise doc.fail(algorithms[1], "expected one osp:Algorithm: which one is meant is not said")
            for algorithm in algorithms:
                chosen = list(algorithm)
                if len(chosen) != 1 or chosen[0].tag != q("osp", "FixedStepAlgorithm"):
                    what = ", ".join(tag_name(c) for c in chosen) or "nothing"
                    raise doc.fail(algorithm, f"not supported: {shorten(what, 200)}; expected one "
                                              "osp:FixedStepAlgorithm (libcosim's and ecos' fixed-step master)")
                fixed = chosen[0]
                base = number(doc, fixed, "baseStepSize")
                if not base > 0:
                    raise doc.fail(fixed, "expected a step > 0 s", "baseStepSize")
                if fixed.get("numWorkerThreads") is not None:
                    # threads change how fast, not what is computed
                    try:
                        if parse_int(fixed.get("numWorkerThreads")) < 0:
                            raise ValueError
                    except ValueError:
                        raise doc.fail(fixed, "expected a whole number >= 0", "numWorkerThreads") from None
                step = (base, fixed)
        for a in self._annotations(exp, "com.github.ecos-platform.scenario"):
            self.warn(doc.label, doc.key(a, "type"), "ecos' scenario (timed changes of variables) is not applied")
        return out, step

    def _annotations(self, el, kind: str) -> list:
        holder = el.find(q("ssd", "Annotations"))
        return [a for a in (holder if holder is not None else [])
                if a.tag == q("ssc", "Annotation") and a.get("type") == kind]

    def _annotation(self, doc: Doc, el, kind: str):
        """The element's one ssc:Annotation of this type, or None (two are refused)."""
        found = self._annotations(el, kind)
        if len(found) > 1:
            raise doc.fail(found[1], "expected one annotation of this type: which one is meant is not said", "type")
        return found[0] if found else None

    def _step_hint(self, doc: Doc, el) -> tuple[float, str, str] | None:
        """A component's osp:StepSizeHint: (step in s, file, key), or None."""
        osp = self._annotation(doc, el, OSP_ANNOTATION)
        if osp is None:
            return None
        hints = []
        for c in osp:
            if c.tag != q("osp", "StepSizeHint"):
                raise doc.fail(c, f"not supported in the OSP annotation of a component: {tag_name(c)}; "
                                  "expected osp:StepSizeHint")
            hints.append(c)
        if len(hints) > 1:
            raise doc.fail(hints[1], "expected one osp:StepSizeHint: which one is meant is not said")
        if not hints:
            return None
        value = number(doc, hints[0], "value")
        if not value > 0:
            raise doc.fail(hints[0], "expected a step > 0 s", "value")
        return value, doc.label, doc.key(hints[0], "value")

    def _master(self, doc: Doc, system, osp_step: tuple | None) -> dict:
        out: dict = {}
        labels: dict[str, tuple[str, str]] = {}
        oms = self._annotation(doc, system, "org.openmodelica")
        if oms is not None:
            fixed = oms.find(f"{{{OMS_NS}}}Annotations/{{{OMS_NS}}}SimulationInformation/{{{OMS_NS}}}FixedStepMaster")
            if fixed is not None and fixed.get("stepSize") is not None:
                out["step"] = number(doc, fixed, "stepSize")
                labels["master.step"] = (doc.label, doc.key(fixed, "stepSize"))
            if fixed is not None and fixed.get("relativeTolerance") is not None and "tolerance" in _MASTER_FIELDS:
                out["tolerance"] = number(doc, fixed, "relativeTolerance")
                labels["master.tolerance"] = (doc.label, doc.key(fixed, "relativeTolerance"))
        if osp_step is not None:
            base, el = osp_step
            if "step" in out and out["step"] != base:
                raise doc.fail(el, f"two steps for the master: OMSimulator's annotation (oms:FixedStepMaster) says "
                                   f"{out['step']:g} s, this one {base:g} s; expected one, or --set master.step",
                               "baseStepSize")
            out["step"] = base
            labels["master.step"] = (doc.label, doc.key(el, "baseStepSize"))
        cw = self._annotation(doc, system, CW_ANNOTATION)
        if cw is not None:
            out = {}  # clockwork's own settings are complete: the other tools' do not mix in
            labels = {}
            m = cw.find(f"{{{CW_NS}}}Settings/{{{CW_NS}}}Master")
            for k, text in (m.attrib.items() if m is not None else []):
                if k not in _MASTER_FIELDS:
                    raise doc.fail(m, f"unknown master setting; allowed: {', '.join(_MASTER_FIELDS)}", k)
                out[k] = _typed(text)
                labels[f"master.{k}"] = (doc.label, doc.key(m, k))
        self.labels.update(labels)
        return out

    def _record(self, doc: Doc, system) -> dict:
        cw = self._annotation(doc, system, CW_ANNOTATION)
        r = cw.find(f"{{{CW_NS}}}Settings/{{{CW_NS}}}Record") if cw is not None else None
        if r is None:
            return {}
        out: dict = {}
        for k, text in r.attrib.items():
            if k not in _RECORD_KEYS:
                raise doc.fail(r, f"unknown record setting; allowed: {', '.join(_RECORD_KEYS)}", k)
            out[k] = _typed(text)
            self.labels[f"record.{k}"] = (doc.label, doc.key(r, k))
        outputs = [o.get("name") for o in r.iterfind(f"{{{CW_NS}}}Output")]
        if outputs:
            out["outputs"] = outputs
        return out

    def _default_record(self) -> list[str]:
        """Every output connector of every component (every output where a
        component declares no connectors)."""
        out = []
        for inst, elem in self.instances.items():
            names = [c.name for c in elem.connectors.values() if self._var(("c", inst, c.name)).causality == "output"]
            if not elem.connectors:
                names = [v.name for v in elem.md.modelVariables if v.causality == "output"]
            out += [f"{inst}.{n}" for n in names
                    if variables_of(elem.md)[n].type in ("Real", "Integer", "Boolean", "Enumeration")]
        return out


def _s(text: object) -> str:
    """A name or value from the file, as an error line echoes it (shortened)."""
    return shorten(text, 100)


def _same_value(a, b) -> bool:
    """Two ssv:Parameter elements that say the same: type, value and unit."""
    def said(p):
        return [(c.tag, sorted(c.attrib.items())) for c in p]
    return said(a) == said(b)


def _unlink(link) -> list:
    """A chain kept as a linked list (step, rest), newest step first, as a list."""
    out = []
    while link is not None:
        out.append(link[0])
        link = link[1]
    return out


def _typed(text: str):
    """An attribute of clockwork's annotation as the TOML value it stands for
    (the numbers through the strict reader: "1_0" stays text and is refused
    where a number is due)."""
    if text in ("true", "false"):
        return text == "true"
    for kind in (parse_int, parse_real):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def _transformation(doc: Doc, el, where: str) -> tuple[float, float]:
    """(factor, offset) of the ssc:LinearTransformation among an element's
    children, (1, 0) without one; any other transformation, or an element
    SSP does not define there, is refused: a link must not lose its factor."""
    factor, offset, seen = 1.0, 0.0, None
    for child in el:
        if child.tag == q("ssc", "LinearTransformation"):
            if seen is not None:
                raise doc.fail(child, "expected one transformation: which one is meant is not said")
            seen = child
            factor = number(doc, child, "factor", 1.0)
            offset = number(doc, child, "offset", 0.0)
        elif child.tag in _INERT:
            continue
        elif child.tag.endswith("MappingTransformation") and child.tag.startswith("{" + NS["ssc"] + "}"):
            raise doc.fail(child, f"not supported: mapping transformations on {where}; expected "
                                  "ssc:LinearTransformation")
        else:
            raise doc.fail(child, f"not supported on {where}: {tag_name(child)}; expected ssc:LinearTransformation "
                                  "(SSP's transformation) or none")
    return factor, offset


def read_ssp(path: str | Path) -> SspScene:
    """An .ssp archive or an .ssd file, read and flattened; raises SceneError."""
    path = Path(path)
    if not path.exists():
        raise SceneError(absent(path, "an .ssp archive or an .ssd file"), path)
    if path.is_dir():
        raise SceneError("is a directory, expected an .ssp archive or an .ssd file", path)
    reader = _Reader(path)
    try:
        return reader.read()
    finally:
        reader.store.close()
