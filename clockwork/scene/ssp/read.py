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

import dataclasses
import hashlib
from dataclasses import dataclass, field
from pathlib import Path

from ...engine.description import FmuError, read_fmu, types_connect, var_unit
from ...engine.description import variables as variables_of
from ...errors import SceneError
from ..checks import Ctx, convert_value
from ..model import Component, Connection, MasterConfig
from .common import CW_ANNOTATION, CW_NS, NS, OMS_NS, VERSIONS, q
from .documents import SSD_NAME, Doc, Store, boolean, conversion, fmu_units, number, unit_table

FMU_TYPE = "application/x-fmu-sharedlibrary"
PSET_TYPE = "application/x-ssp-parameter-set"
PMAP_TYPE = "application/x-ssp-parameter-mapping"
_REALS = ("Real", "Float64", "Float32")
_INTEGERS = ("Integer", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64")
_TYPES = _REALS + _INTEGERS + ("Boolean", "String", "Enumeration")
_FMI_TYPE = {**{t: "Real" for t in _REALS}, **{t: "Integer" for t in _INTEGERS},
             "Boolean": "Boolean", "String": "String", "Enumeration": "Enumeration"}
# What clockwork's annotation may set: MasterConfig fields and record keys.
_RECORD_KEYS = ("interval", "ticks")
# Bounds before the work: each component is an FMU instance (a clock has 2 to 6),
# and each input's sources are found by walking the connections.
MAX_COMPONENTS = 10_000  # validate and run grow linearly: docs/benchmarks.md, "Systems of many FMUs"
MAX_PATH_STEPS = 100_000
_MASTER_FIELDS = tuple(f.name for f in dataclasses.fields(MasterConfig))


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
    aliases: dict[str, str] = field(default_factory=dict)  # system connector -> "instance.output" it passes on


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

    def warn(self, label: str, key: str, text: str) -> None:
        self.warnings.append(f"{label}: {key}: {text}")

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
        sections = {"experiment": self._experiment(doc, root), "master": self._master(doc, system),
                    "record": self._record(doc, system)}
        if "outputs" not in sections["record"]:
            sections["record"]["outputs"] = self._default_record()
        if self.store.zip is not None:
            digest = hashlib.sha256(self.path.read_bytes()).hexdigest()
        else:
            digest = self.store.digest.hexdigest()
        return SspScene(root.get("name") or self.path.stem, system.get("description") or "", components,
                        tuple(connections), sections, digest, self.warnings, self.aliases)

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
                    raise doc.fail(c, f"expected the name of a variable of {md.modelName}: it has no {name}",
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
                        self.warn(doc.label, doc.key(c, "name"), f"the connector is in {unit}, "
                                  f"{md.modelName}.{name} in {var_unit(v)}; the FMU's unit is used")
                    unit = var_unit(v)
                ctype = v.type
            out[name] = _Connector(name, kind, ctype, unit, c)
        return out

    def _system(self, doc: Doc, el, path: str) -> _Element:
        node = _Element(el.get("name") or "", path, True, doc, el, self._connectors(doc, el))
        self.systems[path] = node
        if el.find(q("ssd", "SignalDictionaries")) is not None:
            raise doc.fail(el.find(q("ssd", "SignalDictionaries")), "not supported: signal dictionaries")
        elements = el.find(q("ssd", "Elements"))
        for child in (elements if elements is not None else []):
            ns, _, local = child.tag[1:].partition("}")
            name = child.get("name")
            if ns != NS["ssd"] or local not in ("Component", "System"):
                what = "signal dictionary references" if local == "SignalDictionaryReference" else f"{local} elements"
                raise doc.fail(child, f"not supported: {what}; expected ssd:Component or ssd:System")
            if not name:
                raise doc.fail(child, "expected a non-empty element name", "name")
            if name in node.children:
                raise doc.fail(child, f"expected a unique element name in system {node.name!r}", "name")
            sub = f"{path}.{name}" if path else name
            if local == "System":
                node.children[name] = self._system(doc, child, sub)
            else:
                node.children[name] = self._component(doc, child, sub)
        return node

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
        fmu = self.store.fmu(self.store.resolve(doc, el, "source"))
        try:
            md, digest, indicators = read_fmu(fmu)
        except FmuError as e:
            detail = str(e)
            if "Co-Simulation" in detail:
                detail = ("expected an FMU with Co-Simulation: this one is Model Exchange only "
                          "(clockwork is a co-simulation master)")
            raise doc.fail(el, detail, "source") from None
        impl = el.get("implementation", "any")
        if impl == "ScheduledExecution":
            raise doc.fail(el, "expected any or CoSimulation: scheduled execution is FMI 3.0", "implementation")
        if impl == "ModelExchange":
            self.warn(doc.label, doc.key(el, "implementation"),
                      "asks for Model Exchange; clockwork runs the FMU's Co-Simulation interface")
        node = _Element(el.get("name"), path, False, doc, el, self._connectors(doc, el, md))
        node.fmu_path, node.md, node.digest, node.indicators = fmu, md, digest, indicators
        if path in self.instances:
            raise doc.fail(el, f"expected a unique instance name: {path} names two components once systems "
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
                raise doc.fail(el, f"system {system.name!r} has no connector {conn_name!r}; connectors: "
                                   f"{', '.join(system.connectors) or 'none'}", f"{which}Connector")
            return ("s", system.path, conn_name), c
        target = system.children.get(elem_name)
        if target is None:
            raise doc.fail(el, f"system {system.name!r} has no element {elem_name!r}; elements: "
                               f"{', '.join(system.children) or 'none'}", f"{which}Element")
        c = target.connectors.get(conn_name)
        if c is None:
            raise doc.fail(el, f"{elem_name} has no connector {conn_name!r}; connectors: "
                               f"{', '.join(target.connectors) or 'none'}", f"{which}Connector")
        return (("s" if target.is_system else "c"), target.path, conn_name), c

    def _connections(self, system: _Element) -> None:
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
            factor, offset = 1.0, 0.0
            for child in el:
                ns, _, local = child.tag[1:].partition("}")
                if local == "LinearTransformation" and ns == NS["ssc"]:
                    factor = number(doc, child, "factor", 1.0)
                    offset = number(doc, child, "offset", 0.0)
                elif local.endswith("MappingTransformation"):
                    raise doc.fail(child, "not supported: mapping transformations on connections; "
                                          "expected ssc:LinearTransformation")
            self.edges.append(_Edge(a, b, factor, offset, boolean(doc, el, "suppressUnitConversion"), doc, el))
        for child in system.children.values():
            if child.is_system:
                self._connections(child)

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
        self.aliases = {}
        for node in adj:
            if node[0] == "s":
                self._alias(node, adj)
            if self._role(node) != "sink":
                continue
            found = self._walk(node, adj)
            sources = [f for f in found if f[0][0] == "c"]
            if len(sources) > 1:
                names = " and ".join(f"{s[1]}.{s[2]}" for s, _ in sources)
                e = sources[1][1][-1][0]
                raise e.doc.fail(e.el, f"input {node[1]}.{node[2]} is fed by two outputs: {names}")
            if sources:
                src, chain = sources[0]
                if self._var(node).causality != "input":
                    raise chain[-1][0].doc.fail(chain[-1][0].el, f"expected an input at the end: {node[1]}.{node[2]} "
                                                                 f"is a {self._var(node).causality}, which an output cannot feed")
                factor, offset = self._chain(chain, self._var(src), self._var(node))
                links[(node[1], node[2])] = ((src[1], src[2]), factor, offset)
            else:
                # fed only by system connectors: they may carry a parameter value
                fed[(node[1], node[2])] = [(s, chain) for s, chain in found]
        return links, fed

    def _walk(self, node: tuple, adj: dict) -> list:
        """What feeds `node`: [(source node, [(edge, upstream, downstream)] in data-flow order)],
        a component output, or a system connector with nothing upstream."""
        found = []
        visits = [0]

        def walk(cur, chain, seen):
            for e, other in adj.get(cur, []):
                if other in seen:
                    continue
                visits[0] += 1
                if visits[0] > MAX_PATH_STEPS:  # loops of system connectors: the paths grow as n!
                    raise e.doc.fail(e.el, f"more than {MAX_PATH_STEPS:,} paths through system connectors lead to "
                                           f"{'.'.join(n for n in node[1:] if n)}: expected connections without loops")
                role = self._role(other)
                step = [(e, other, cur)] + chain
                if role == "source":
                    found.append((other, step))
                elif role == "through":
                    before = len(found)
                    walk(other, step, seen | {other})
                    if len(found) == before:
                        found.append((other, step))
        walk(node, [], {node})
        return found

    def _alias(self, node: tuple, adj: dict) -> None:
        """A system connector that passes one component output on unchanged
        can be recorded by its name ("wB", "sub.w"): it records that output."""
        sources = [f for f in self._walk(node, adj) if f[0][0] == "c"]
        if len(sources) != 1:
            return
        src, chain = sources[0]
        try:
            var = self._var(src)
            if self._chain(chain, var, var) != (1.0, 0.0):
                return
        except SceneError:
            return
        name = f"{node[1]}.{node[2]}" if node[1] else node[2]
        self.aliases[name] = f"{src[1]}.{src[2]}"

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

    def _bindings(self, system: _Element) -> dict[tuple, tuple]:
        """{node: (value, type, unit, label, key)}, the SSP's precedence applied."""
        values: dict[tuple, tuple] = {}
        for child in system.children.values():
            if child.is_system:
                values.update(self._bindings(child))
            else:
                for name, v in self._element_values(child):
                    self._assign(child, name, v, values, exact=True)
        for name, v in self._element_values(system):
            self._assign(system, name, v, values, exact=False)
        return values

    def _assign(self, elem: _Element, name: str, v: tuple, values: dict, exact: bool) -> None:
        targets = [("c", elem.path, name)] if not elem.is_system else self._resolve(elem, name)
        if not elem.is_system and name not in variables_of(elem.md):
            targets = []
        if not targets:
            self.warn(v[3], v[4], f"{name} names no variable of {elem.path or elem.name!r}; ignored "
                                  "(SSP: a parameter value without a match is not applied)")
        for t in targets:
            values[t] = v

    def _resolve(self, system: _Element, name: str) -> list[tuple]:
        """Every variable a hierarchical name reaches in a system (SSP allows punning)."""
        out = []
        if name in system.connectors:
            out.append(("s", system.path, name))
        for ename, child in system.children.items():
            if name.startswith(ename + "."):
                rest = name[len(ename) + 1:]
                if child.is_system:
                    out += self._resolve(child, rest)
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
        holder = pset.find(q("ssv", "Parameters"))
        for p in (holder if holder is not None else []):
            if p.tag != q("ssv", "Parameter"):
                raise doc.fail(p, "expected ssv:Parameter elements only")
            name = p.get("name")
            if not name:
                raise doc.fail(p, "expected a parameter name", "name")
            typed = [c for c in p if c.tag.startswith("{" + NS["ssv"] + "}")]
            typed = [c for c in typed if c.tag.partition("}")[2] not in ("Annotations",)]
            if len(typed) != 1:
                raise doc.fail(p, "expected one value element (ssv:Real, ssv:Integer, ssv:Boolean, ...)")
            t = typed[0]
            local = t.tag.partition("}")[2]
            if local not in _TYPES:
                raise doc.fail(t, f"not supported: {local} parameters; expected Real, Integer, Boolean, String "
                                  "or Enumeration")
            text = t.get("value")
            if text is None:
                raise doc.fail(t, "missing required attribute", "value")
            kind = _FMI_TYPE[local]
            if kind == "Real":
                value: object = number(doc, t, "value")
            elif kind == "Integer":
                try:
                    value = int(text)
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
                what = "an empty source names no parameter" if not src else f"the parameter set has no {src}"
                self.warn(mdoc.label, mdoc.key(m, "source"), f"{what}; entry not applied")
                continue
            value, kind, unit, label, key, units = by_name[src]
            suppress = boolean(mdoc, m, "suppressUnitConversion")
            transform = None
            for child in m:
                local = child.tag.partition("}")[2]
                if local == "LinearTransformation":
                    transform = (number(mdoc, child, "factor", 1.0), number(mdoc, child, "offset", 0.0))
                elif local.endswith("Transformation"):
                    raise mdoc.fail(child, "not supported: mapping transformations other than ssc:LinearTransformation")
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
            if variable.causality not in ("parameter", "input"):
                raise SceneError(f"expected a parameter or an input: {elem.md.modelName}.{var} is "
                                 f"{'an' if variable.causality[0] in 'aeiou' else 'a'} {variable.causality}",
                                 label, key)
            if (inst, var) in linked and variable.causality == "input":
                self.warn(label, key, f"{inst}.{var} is a connected input; its connection wins over this value")
                continue
            params[inst][var] = self._value(v, variable, elem, label, key)
        out = {}
        for inst, elem in self.instances.items():
            out[inst] = Component(inst, elem.fmu_path, elem.digest, elem.md, params[inst], elem.indicators)
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

    def _experiment(self, doc: Doc, root) -> dict:
        exp = root.find(q("ssd", "DefaultExperiment"))
        out = {}
        if exp is not None:
            if exp.get("startTime") is not None:
                out["start"] = number(doc, exp, "startTime")
            if exp.get("stopTime") is not None:
                out["stop"] = number(doc, exp, "stopTime")
        return out

    def _annotation(self, system, kind: str):
        holder = system.find(q("ssd", "Annotations"))
        for a in (holder if holder is not None else []):
            if a.tag == q("ssc", "Annotation") and a.get("type") == kind:
                return a
        return None

    def _master(self, doc: Doc, system) -> dict:
        out: dict = {}
        oms = self._annotation(system, "org.openmodelica")
        if oms is not None:
            fixed = oms.find(f"{{{OMS_NS}}}Annotations/{{{OMS_NS}}}SimulationInformation/{{{OMS_NS}}}FixedStepMaster")
            if fixed is not None and fixed.get("stepSize") is not None:
                out["step"] = number(doc, fixed, "stepSize")
            if fixed is not None and fixed.get("relativeTolerance") is not None and "tolerance" in _MASTER_FIELDS:
                out["tolerance"] = number(doc, fixed, "relativeTolerance")
        cw = self._annotation(system, CW_ANNOTATION)
        if cw is not None:
            out = {}  # clockwork's own settings are complete: OMSimulator's do not mix in
            m = cw.find(f"{{{CW_NS}}}Settings/{{{CW_NS}}}Master")
            for k, text in (m.attrib.items() if m is not None else []):
                if k not in _MASTER_FIELDS:
                    raise doc.fail(m, f"unknown master setting; allowed: {', '.join(_MASTER_FIELDS)}", k)
                out[k] = _typed(text)
        return out

    def _record(self, doc: Doc, system) -> dict:
        cw = self._annotation(system, CW_ANNOTATION)
        r = cw.find(f"{{{CW_NS}}}Settings/{{{CW_NS}}}Record") if cw is not None else None
        if r is None:
            return {}
        out: dict = {}
        for k, text in r.attrib.items():
            if k not in _RECORD_KEYS:
                raise doc.fail(r, f"unknown record setting; allowed: {', '.join(_RECORD_KEYS)}", k)
            out[k] = _typed(text)
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


def _typed(text: str):
    if text in ("true", "false"):
        return text == "true"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def read_ssp(path: str | Path) -> SspScene:
    """An .ssp archive or an .ssd file, read and flattened; raises SceneError."""
    path = Path(path)
    if not path.exists():
        raise SceneError("no such file", path)
    if path.is_dir():
        raise SceneError("is a directory, expected an .ssp archive or an .ssd file", path)
    reader = _Reader(path)
    try:
        return reader.read()
    finally:
        reader.store.close()
