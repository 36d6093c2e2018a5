"""The SSP reader's third job: parameter values. The ssd:ParameterBindings of
every component and system, inline or from .ssv files, through .ssm
parameter mappings, resolved with the SSP's rules of precedence (a later
binding over an earlier one, a system's over its elements') and of
hierarchical names and prefixes; a system connector's value reaches the
component variables it feeds (flatten.py's chains); each value converted
to its variable's unit and checked against its type and range as a
scene's would be (scene/checks.py). The result: the components, each with
its parameters.
"""

from __future__ import annotations

from pathlib import Path

from ...fmi.description import var_unit
from ...fmi.description import variables as variables_of
from ...errors import SceneError
from ...numbers import parse_int, shorten
from ..checks import SETTABLE, STRUCTURAL, Ctx, convert_value, settable_problem
from ..model import Component
from .common import NS, VERSIONS, q
from .documents import Doc, boolean, conversion, fmu_units, number, unit_table
from .flatten import Flat
from .structure import FMI_TYPE, TYPES, Element, Structure, shown, transformation

PSET_TYPE = "application/x-ssp-parameter-set"
PMAP_TYPE = "application/x-ssp-parameter-mapping"


class Parameters:
    """The parameter values of a `Structure`, bound and resolved
    (``bindings``) and given to its components (``components``). A value
    travels as (value, type, unit, file, key, unit tables[, (factor,
    offset) of its mapping]) until it is converted."""

    def __init__(self, structure: Structure, flat: Flat):
        self.structure = structure
        self.flat = flat
        self.warn = structure.warnings.warn

    def bindings(self, top: Element) -> dict[tuple, tuple]:
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

    def _assign(self, elem: Element, name: str, v: tuple, values: dict, exact: bool) -> None:
        targets = [("c", elem.path, name)] if not elem.is_system else self._resolve(elem, name)
        if not elem.is_system and name not in variables_of(elem.md):
            targets = []
        if not targets:
            self.warn(v[3], v[4], f"{shorten(name, 100)} names no variable of {elem.path or elem.name!r}; ignored "
                                  "(SSP: a parameter value without a match is not applied)",
                      "parameter values that name no variable (not applied)")
        for t in targets:
            values[t] = v

    def _resolve(self, system: Element, name: str) -> list[tuple]:
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

    def _element_values(self, elem: Element) -> list[tuple[str, tuple]]:
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
                sdoc = self.structure.store.doc(self.structure.store.resolve(doc, b, "source"), "ssv:ParameterSet")
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
        units = {**self.structure.units, **unit_table(doc, pset.find(q("ssv", "Units")))}
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
            if local not in TYPES:
                raise doc.fail(t, f"not supported: {shown(local)} parameters; expected Real, Integer, Boolean, String "
                                  "or Enumeration")
            text = t.get("value")
            if text is None:
                raise doc.fail(t, "missing required attribute", "value")
            kind = FMI_TYPE[local]
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
            store = self.structure.store
            mdoc = store.doc(store.resolve(doc, mapping, "source"), "ssm:ParameterMapping")
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
                what = "an empty source names no parameter" if not src else f"the parameter set has no {shown(src)}"
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
            transform = transformation(mdoc, m, "parameter mapping entries")  # refuses any other kind
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

    def components(self, values: dict, fed: dict) -> dict[str, Component]:
        params: dict[str, dict] = {inst: {} for inst in self.structure.instances}
        linked = set()
        for e in self.structure.edges:
            for n in (e.a, e.b):
                if n[0] == "c" and self.flat.role(n) == "sink":
                    linked.add((n[1], n[2]))
        # values of system connectors reach the variables they feed
        for (inst, var), sources in fed.items():
            for snode, chain in sources:
                if snode in values:
                    v = values[snode]
                    factor, offset = self.flat.chain(chain, None, self.flat.var(("c", inst, var)))
                    if (factor, offset) != (1.0, 0.0) and v[1] == "Real":
                        # in the system connector's unit, then through the connections
                        x = factor * self._real(v, self.flat.unit(snode), ()) + offset
                        v = (x, "Real", None, v[3], v[4], v[5])
                    values.setdefault(("c", inst, var), v)
                    linked.discard((inst, var))
        for node, v in values.items():
            if node[0] != "c":
                continue
            inst, var = node[1], node[2]
            elem = self.structure.instances[inst]
            variable = variables_of(elem.md)[var]
            label, key = v[3], v[4]
            if variable.causality == "structuralParameter":
                raise SceneError(f"{elem.md.modelName}.{shown(var)} {STRUCTURAL}", label, key)
            problem = settable_problem(variable)
            if problem:
                raise SceneError(f"expected {SETTABLE}: {elem.md.modelName}.{shown(var)} is "
                                 f"{'an' if variable.causality[0] in 'aeiou' else 'a'} {variable.causality} "
                                 f"({problem})", label, key)
            if (inst, var) in linked and variable.causality == "input":
                self.warn(label, key, f"{shown(inst + '.' + var)} is a connected input; its connection wins over this "
                                      "value",
                          "values for connected inputs (the connection wins)")
                continue
            params[inst][var] = self._value(v, variable, elem, label, key)
        out = {}
        for inst, elem in self.structure.instances.items():
            out[inst] = Component(inst, elem.fmu_path, elem.digest, elem.md, params[inst], elem.indicators,
                                  interface=elem.interface, fmu_label=elem.fmu_label)
        return out

    def _value(self, v: tuple, variable, elem: Element, label: str, key: str):
        value, kind, unit = v[0], v[1], v[2]
        ctx = Ctx(Path(label), {})
        if kind != FMI_TYPE.get(variable.type, variable.type) and not (
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
        conv = conversion(v[2], unit, v[5], self.structure.units, *tables)
        if isinstance(conv, str):
            raise SceneError(f"expected convertible units: {conv}", v[3], v[4])
        if conv != (1.0, 0.0):
            value = conv[0] * value + conv[1]
        if len(v) > 6:
            value = v[6][0] * value + v[6][1]
        return value


def _same_value(a, b) -> bool:
    """Two ssv:Parameter elements that say the same: type, value and unit."""
    def said(p):
        return [(c.tag, sorted(c.attrib.items())) for c in p]
    return said(a) == said(b)
