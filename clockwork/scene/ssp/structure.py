"""The structure of an SSD: its systems, components (FMUs), connectors and
connections, read and checked as the document writes them, nested (the
first of the SSP reader's three jobs; read.py runs them, flatten.py and
parameters.py do the others).

``Structure.read`` walks the ssd:System depth first and records every
component as an ``Element`` under its hierarchical instance name
(``sub.comp``) and every ssd:Connection as an ``Edge`` between two
connector nodes, ``("c", instance, variable)`` for a component's and
``("s", system path, connector)`` for a system's.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ...fmi.description import FmuError, read_fmu, var_unit
from ...fmi.description import variables as variables_of
from ...engine.model_exchange import interface_of, model_exchange_problem
from ...errors import SceneError
from ...numbers import shorten
from ..checks import instance_problem
from .common import NS, OSP_ANNOTATION, Warnings, q
from .documents import Doc, Store, boolean, conversion, fmu_units, number, tag_name

FMU_TYPE = "application/x-fmu-sharedlibrary"
REALS = ("Real", "Float64", "Float32")
INTEGERS = ("Integer", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64")
TYPES = REALS + INTEGERS + ("Boolean", "String", "Enumeration")
# SSP's (and FMI 3.0's) type names -> FMI 2.0's
FMI_TYPE = {**{t: "Real" for t in REALS}, **{t: "Integer" for t in INTEGERS},
            "Boolean": "Boolean", "String": "String", "Enumeration": "Enumeration"}
# What the SSP may hold around a connection's or mapping entry's transformation
# without changing the simulation (the drawing, tools' annotations).
_INERT = {q("ssd", "ConnectionGeometry"), q("ssd", "Annotations"), q("ssc", "Annotations")}


@dataclass
class Connector:
    name: str
    kind: str
    type: str | None  # FMI type name from the ssc type element, None if not given
    unit: str | None
    el: object


@dataclass
class Element:
    name: str  # as in the SSD
    path: str  # hierarchical: "" for the top-level system, "sub", "sub.comp"
    is_system: bool
    doc: Doc
    el: object
    connectors: dict[str, Connector]
    children: dict[str, "Element"] = field(default_factory=dict)
    fmu_path: Path | None = None
    fmu_label: str = ""  # an archive's FMU as messages name it (archive/member); "": its path
    interface: str | None = None  # "model-exchange" or "co-simulation" as implementation= asks; None: any
    md: object = None
    digest: str = ""
    indicators: tuple = ()
    connections: list = field(default_factory=list)


@dataclass
class Edge:
    a: tuple  # ("c", instance, variable) or ("s", system path, connector)
    b: tuple
    factor: float
    offset: float
    suppress: bool
    doc: Doc
    el: object


class Structure:
    """The systems and components of one SSD, and its connections: what
    the document says, checked, not yet flattened.

    Attributes:
        store: The archive or folder the documents are read from.
        units: The SSD's ssd:Units, by name.
        instances: {hierarchical instance name: its component}, in
            document order.
        systems: {system path ("" the top one): its system}.
        edges: Every ssd:Connection of every system.
        step_hints: {instance: (step in s, file, key)}: the components'
            osp:StepSizeHint.
        warnings: Where warnings go (read.py's, shared by the three jobs).
        max_components: The most components read (read.MAX_COMPONENTS).
    """

    def __init__(self, store: Store, warnings: Warnings, max_components: int):
        self.store = store
        self.warnings = warnings
        self.max_components = max_components
        self.units: dict = {}
        self.instances: dict[str, Element] = {}
        self.systems: dict[str, Element] = {}
        self.edges: list[Edge] = []
        self.step_hints: dict[str, tuple[float, str, str]] = {}

    def read(self, doc: Doc, system) -> Element:
        """The top-level system (`system`, the SSD's ssd:System) and
        everything below it, with its connections."""
        top = self._system(doc, system, "")
        if not self.instances:
            raise doc.fail(system, "expected at least one ssd:Component (an FMU) in the system or its sub-systems")
        self.connections(top)
        return top

    def _connectors(self, doc: Doc, el, md=None) -> dict[str, Connector]:
        out: dict[str, Connector] = {}
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
                if ns == NS["ssc"] and (local in TYPES or local == "Binary"):  # Binary: FMI 3.0's
                    ctype = FMI_TYPE.get(local, local)
                    unit = (child.get("unit") or None) if ctype == "Real" else None  # unit="" is no unit
                elif ns == NS["ssc"] and local == "Clock":  # SSP 2.0: an FMI 3.0 clock (docs/clocks.md)
                    ctype = "Clock"
            if c.find(q("ssc", "Dimension")) is not None or c.find(q("ssd", "Dimension")) is not None:
                raise doc.fail(c, "not supported: array connectors (ssc:Dimension)")
            if variables is not None:
                v = variables.get(name)
                if v is None:
                    raise doc.fail(c, f"expected the name of a variable of {md.modelName}: it has no {shown(name)}",
                                   "name")
                if ctype is not None and ctype != FMI_TYPE.get(v.type, v.type) and not (
                        ctype == "Integer" and v.type == "Enumeration"):
                    raise doc.fail(c, f"type mismatch: the connector is {ctype}, {md.modelName}.{name} is {v.type}")
                if kind in ("input", "output") and v.causality != kind:
                    raise doc.fail(c, f"expected kind={v.causality!r}: {md.modelName}.{name} is "
                                      f"{'an' if v.causality[0] in 'aeiou' else 'a'} {v.causality}", "kind")
                if v.type == "Real" and var_unit(v) is not None:
                    # the FMU's unit is what its numbers are in
                    if unit is not None and conversion(unit, var_unit(v), self.units, fmu_units(md)) != (1.0, 0.0):
                        self.warnings.warn(doc.label, doc.key(c, "name"), f"the connector is in {shorten(unit, 100)}, "
                                  f"{md.modelName}.{name} in {var_unit(v)}; the FMU's unit is used",
                                  "connector units that differ from the FMU's (the FMU's is used)")
                    unit = var_unit(v)
                ctype = v.type
            out[name] = Connector(name, kind, ctype, unit, c)
        return out

    def _system(self, doc: Doc, el, path: str) -> Element:
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

    def _new_system(self, doc: Doc, el, path: str) -> Element:
        node = Element(el.get("name") or "", path, True, doc, el, self._connectors(doc, el))
        self.systems[path] = node
        if el.find(q("ssd", "SignalDictionaries")) is not None:
            raise doc.fail(el.find(q("ssd", "SignalDictionaries")), "not supported: signal dictionaries")
        return node

    @staticmethod
    def _elements(doc: Doc, el) -> list:
        elements = el.find(q("ssd", "Elements"))
        return list(elements) if elements is not None else []

    def _component(self, doc: Doc, el, path: str) -> Element:
        ctype = el.get("type", FMU_TYPE)
        if ctype in ("application/x-ssp-definition", "application/x-ssp-package"):
            raise doc.fail(el, "not supported: a component that references another SSD or SSP; "
                               f"expected {FMU_TYPE}", "type")
        if ctype != FMU_TYPE:
            raise doc.fail(el, f"expected type {FMU_TYPE} (an FMU)", "type")
        if el.get("source") is None:
            raise doc.fail(el, "missing required attribute; expected the FMU's path", "source")
        if len(self.instances) >= self.max_components:
            raise doc.fail(el, f"more than {self.max_components} components (FMU instances) in the system and its "
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
        node = Element(el.get("name"), path, False, doc, el, self._connectors(doc, el, md))
        node.fmu_path, node.md, node.digest, node.indicators = fmu, md, digest, indicators
        node.fmu_label = label or ""
        node.interface = interface
        hint = self._step_hint(doc, el)
        if hint is not None:
            self.step_hints[path] = hint
        if path in self.instances:
            raise doc.fail(el, f"expected a unique instance name: {shown(path)} names two components once systems "
                               "are flattened", "name")
        self.instances[path] = node
        return node

    def _end(self, system: Element, doc: Doc, el, which: str) -> tuple[tuple, Connector]:
        # an empty element name (OMSimulator writes one) is the system's own connector
        elem_name, conn_name = el.get(f"{which}Element") or None, el.get(f"{which}Connector")
        if conn_name is None:
            raise doc.fail(el, "missing required attribute", f"{which}Connector")
        if elem_name is None:
            c = system.connectors.get(conn_name)
            if c is None:
                raise doc.fail(el, f"system {shown(system.name)!r} has no connector {shown(conn_name)!r}; connectors: "
                                   f"{shown(', '.join(system.connectors) or 'none')}", f"{which}Connector")
            return ("s", system.path, conn_name), c
        target = system.children.get(elem_name)
        if target is None:
            raise doc.fail(el, f"system {shown(system.name)!r} has no element {shown(elem_name)!r}; elements: "
                               f"{shown(', '.join(system.children) or 'none')}", f"{which}Element")
        c = target.connectors.get(conn_name)
        if c is None:
            raise doc.fail(el, f"{shown(elem_name)} has no connector {shown(conn_name)!r}; connectors: "
                               f"{shown(', '.join(target.connectors) or 'none')}", f"{which}Connector")
        return (("s" if target.is_system else "c"), target.path, conn_name), c

    def connections(self, top: Element) -> None:
        todo = [top]  # systems, depth first in document order (a stack, not recursion)
        while todo:
            system = todo.pop()
            self._system_connections(system)
            todo += reversed([c for c in system.children.values() if c.is_system])

    def _system_connections(self, system: Element) -> None:
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
            factor, offset = transformation(doc, el, "connections")
            self.edges.append(Edge(a, b, factor, offset, boolean(doc, el, "suppressUnitConversion"), doc, el))

    def annotations(self, el, kind: str) -> list:
        holder = el.find(q("ssd", "Annotations"))
        return [a for a in (holder if holder is not None else [])
                if a.tag == q("ssc", "Annotation") and a.get("type") == kind]

    def annotation(self, doc: Doc, el, kind: str):
        """The element's one ssc:Annotation of this type, or None (two are refused)."""
        found = self.annotations(el, kind)
        if len(found) > 1:
            raise doc.fail(found[1], "expected one annotation of this type: which one is meant is not said", "type")
        return found[0] if found else None

    def _step_hint(self, doc: Doc, el) -> tuple[float, str, str] | None:
        """A component's osp:StepSizeHint: (step in s, file, key), or None."""
        osp = self.annotation(doc, el, OSP_ANNOTATION)
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


def shown(text: object) -> str:
    """A name or value from the file, as an error line echoes it (shortened)."""
    return shorten(text, 100)


def transformation(doc: Doc, el, where: str) -> tuple[float, float]:
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
