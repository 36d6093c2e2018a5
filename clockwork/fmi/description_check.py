"""One pass over a modelDescription.xml before fmpy reads it.

fmpy reads a model description without checking what the layers above rely
on: its numbers go through Python's ``int()`` and ``float()`` (``"1_0"`` is
10, ``"zero"`` a ValueError), a ModelStructure entry naming a missing
variable is a bare KeyError (``21``), and duplicate names or value
references pass. ``check_description`` reads the same XML once and refuses
all of that with one line naming the element, its line and what was
expected, the same rules for FMI 1.0, 2.0 and 3.0 where the versions share
them:

- every variable has a name, unique (FMI 3.0 aliases included; FMI 1.0
  internal variables excepted, see ``_internal``), and a value reference,
  an unsigned 32-bit integer; in FMI 3.0 no two variables share one (FMI
  1.0 and 2.0 make variables of one base type on one value reference
  aliases, which is allowed);
- one type element per FMI 1.0/2.0 variable, a known type in FMI 3.0, and
  a declared type that exists and is of the variable's type;
- ``start``, ``min``, ``max`` and ``nominal`` of each variable and type
  definition are numbers of the variable's type (xs:double with INF and
  NaN for Real/Float, integers in the type's range, xs:boolean), one value
  for a scalar, and ``min <= max``; a unit's factor is a number other than
  0 (a conversion divides by it);
- ModelStructure entries, ``derivative``, ``clocks`` and Dimension
  references name variables that exist;
- the attributes that clockwork or fmpy convert to numbers
  (DefaultExperiment, maxOutputDerivativeOrder, numberOfEventIndicators).

A start value outside [min, max] is not refused: FMUs exported by tools in
use have them, and a value the scene sets is range-checked where it is set.
"""

from __future__ import annotations

import math

from lxml import etree

from ..numbers import XSD_SPECIAL, parse_int, parse_real, shorten
from .types import INT_RANGES

# The integer types and their ranges: FMI 1.0/2.0's Integer is a C int, FMI
# 3.0's sized types keep their own names (and fmi3Get/Set* functions).
FLOAT32_MAX = 3.4028234663852886e38

_SCALAR_TYPES = ("Real", "Integer", "Boolean", "String", "Enumeration")  # FMI 1.0 and 2.0
_FMI3_TYPES = ("Float32", "Float64", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64",
               "Boolean", "String", "Binary", "Enumeration", "Clock")
_REALS = ("Real", "Float32", "Float64")
_BOOLEANS = {"true": True, "false": False, "1": True, "0": False}
_VR_MAX = 2**32 - 1
_CAUSALITIES = {"1.0": ("input", "output", "internal", "none"),
                "2.0": ("parameter", "calculatedParameter", "input", "output", "local", "independent"),
                "3.0": ("structuralParameter", "parameter", "calculatedParameter", "input", "output", "local",
                        "independent")}
_VARIABILITIES = {"1.0": ("constant", "parameter", "discrete", "continuous"),
                  "2.0": ("constant", "fixed", "tunable", "discrete", "continuous"),
                  "3.0": ("constant", "fixed", "tunable", "discrete", "continuous")}
# FMI 3.0 ModelStructure elements; FMI 2.0's hold <Unknown> elements.
_FMI3_STRUCTURE = ("Output", "ContinuousStateDerivative", "ClockedState", "InitialUnknown", "EventIndicator")
_FMI2_STRUCTURE = ("Outputs", "Derivatives", "InitialUnknowns")

_PARSER = etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False,
                          remove_comments=True, remove_pis=True)


class DescriptionProblem(ValueError):
    """str() is what is wrong, where: "line 12: Float64 'x' min='zero': expected a number"."""


def _internal(v) -> bool:
    """An FMI 1.0 variable no other tool sees: exporters have written two such
    variables of one name (ecos' dp_ship DPController), and fmpy, libcosim
    and ecos run them."""
    return v.get("causality", "internal") == "internal"


def _where(el, attr: str | None = None) -> str:
    name = el.get("name")
    what = f"{el.tag} {shorten(name, 80)!r}" if name is not None and attr != "name" else str(el.tag)
    if attr is not None:
        value = el.get(attr)
        what += f" {attr}" if value is None else f" {attr}={shorten(value, 80)!r}"
    return f"line {el.sourceline}: {what}"


def _fail(el, detail: str, attr: str | None = None) -> DescriptionProblem:
    return DescriptionProblem(f"{_where(el, attr)}: {detail}")


def check_description(xml: bytes) -> None:
    """Refuse what the description says wrong (DescriptionProblem); an FMI
    version other than 1.0, 2.0 or 3.0 is left to the caller."""
    try:
        root = etree.fromstring(xml, _PARSER)
    except etree.XMLSyntaxError as e:
        raise DescriptionProblem(f"malformed XML: {shorten(e, 200)}") from None
    if root is None or not isinstance(root.tag, str):
        raise DescriptionProblem("malformed XML: no root element")
    if root.tag != "fmiModelDescription":
        raise _fail(root, "expected the root element fmiModelDescription")
    version = root.get("fmiVersion") or ""
    major = "3.0" if version.startswith("3.") else version
    if major not in ("1.0", "2.0", "3.0"):
        return
    _Pass(root, major).run()


class _Pass:
    def __init__(self, root, version: str):
        self.root = root
        self.version = version
        self.fmi3 = version == "3.0"
        self.types: dict[str, str] = {}  # declared type name -> its variable type
        # FMI 3.0's Enumeration is an Int64, FMI 1.0/2.0's an Integer
        self.enum_range = INT_RANGES["Int64" if self.fmi3 else "Integer"]

    def run(self) -> None:
        root = self.root
        for attr in ("numberOfEventIndicators", "numberOfContinuousStates"):
            self.integer(root, attr, 0, _VR_MAX)
        for d in root.iterfind("DefaultExperiment"):
            # xs:double, INF and NaN included: the schema allows them, and an FMU is usable in a scene that
            # takes none of these defaults; where one is used it is refused if unusable, by its name
            # (scene/fmu.py for an FMU run alone, description.default_tolerance_problem)
            for attr in ("startTime", "stopTime", "tolerance", "stepSize"):
                if d.get(attr) is not None:
                    self.real(d, attr)
        for cs in root.iterfind("CoSimulation"):
            self.integer(cs, "maxOutputDerivativeOrder", 0, _VR_MAX)
        self.units()
        self.type_definitions()
        variables = self.variables()
        self.structure(variables)

    # -- numbers

    def real(self, el, attr: str) -> float:
        try:
            return parse_real(el.get(attr), XSD_SPECIAL)
        except ValueError:
            raise _fail(el, "expected a number (xs:double)", attr) from None

    def integer(self, el, attr: str, lo: int, hi: int) -> int | None:
        text = el.get(attr)
        if text is None:
            return None
        try:
            x = parse_int(text)
        except ValueError:
            raise _fail(el, "expected an integer", attr) from None
        if not lo <= x <= hi:
            raise _fail(el, f"expected an integer in [{lo}, {hi}]", attr)
        return x

    def values(self, el, attr: str, vtype: str, array: bool) -> list:
        """The value(s) of a start/min/max/nominal attribute, checked against the type."""
        text = el.get(attr)
        if text is None:
            return []
        tokens = text.split() if self.fmi3 else [text]
        # an array's start is an xs:list, which may be empty (an array of size 0); its count against the
        # array's size is checked where the sizes are known (description._check_arrays)
        if (not tokens and not array) or (len(tokens) > 1 and not array):
            why = " (the variable has no Dimension)" if len(tokens) > 1 else ""
            raise _fail(el, f"expected {'values' if array else 'one value'} of type {vtype}{why}", attr)
        out = []
        for tok in tokens:
            if vtype in _REALS:
                try:
                    x = parse_real(tok, XSD_SPECIAL)
                except ValueError:
                    raise _fail(el, f"expected a number (xs:double){' list' * array}", attr) from None
                if vtype == "Float32" and math.isfinite(x) and abs(x) > FLOAT32_MAX:
                    raise _fail(el, f"expected a Float32 value, in [-{FLOAT32_MAX:g}, {FLOAT32_MAX:g}]", attr)
            elif vtype in INT_RANGES or vtype == "Enumeration":
                try:
                    x = parse_int(tok)
                except ValueError:
                    raise _fail(el, f"expected an integer{' list' * array} ({vtype})", attr) from None
                lo, hi = INT_RANGES.get(vtype) or self.enum_range
                if not lo <= x <= hi:
                    raise _fail(el, f"expected a {vtype} value, in [{lo}, {hi}]", attr)
            elif vtype == "Boolean":
                if tok not in _BOOLEANS:
                    raise _fail(el, "expected true or false", attr)
                x = _BOOLEANS[tok]
            else:
                x = tok
            out.append(x)
        return out

    def limits(self, el, vtype: str, array: bool = False) -> None:
        """min, max and nominal of a variable or type definition, and min <= max."""
        if vtype not in _REALS and vtype not in INT_RANGES and vtype != "Enumeration":
            return
        lo = self.values(el, "min", vtype, False)
        hi = self.values(el, "max", vtype, False)
        if vtype in _REALS:
            self.values(el, "nominal", vtype, array)
        if lo and hi and not lo[0] <= hi[0]:
            raise _fail(el, f"expected min <= max, got min={shorten(el.get('min'), 60)} and "
                            f"max={shorten(el.get('max'), 60)}")

    # -- units and types

    def units(self) -> None:
        if self.version == "1.0":
            for d in self.root.iterfind("UnitDefinitions/BaseUnit/DisplayUnitDefinition"):
                self.factor(d, "gain")
                if d.get("offset") is not None:
                    self.real(d, "offset")
            return
        for u in self.root.iterfind("UnitDefinitions/Unit"):
            # Required, but "" is a valid xs:normalizedString (PythonFMU writes <Unit name="">).
            if u.get("name") is None:
                raise _fail(u, "missing required attribute; expected a unit name", "name")
            for b in u.iterfind("BaseUnit"):
                for k in ("kg", "m", "s", "A", "K", "mol", "cd", "rad"):
                    self.integer(b, k, -2**31, 2**31 - 1)
                self.factor(b, "factor")
                if b.get("offset") is not None:
                    self.real(b, "offset")
            for d in u.iterfind("DisplayUnit"):
                self.factor(d, "factor")
                if d.get("offset") is not None:
                    self.real(d, "offset")

    def factor(self, el, attr: str) -> None:
        if el.get(attr) is None:
            return
        x = self.real(el, attr)
        if not math.isfinite(x) or x == 0:
            raise _fail(el, "expected a finite number other than 0 (a conversion divides by it)", attr)

    def type_definitions(self) -> None:
        holder = self.root.find("TypeDefinitions")
        for t in (holder if holder is not None else []):
            if not isinstance(t.tag, str):
                continue
            if self.fmi3:
                if not t.tag.endswith("Type") or t.tag[:-4] not in _FMI3_TYPES:
                    continue  # fmpy skips them too (ClockType...)
                body, vtype = t, t.tag[:-4]
            else:
                body = t[0] if len(t) else None
                if t.tag != ("Type" if self.version == "1.0" else "SimpleType"):
                    continue
                kind = None if body is None else (body.tag[:-4] if self.version == "1.0" else body.tag)
                if kind not in _SCALAR_TYPES:
                    raise _fail(t, f"expected one type element ({', '.join(_SCALAR_TYPES)})")
                vtype = kind
            name = t.get("name")
            if name is None:  # required; "" is a valid xs:normalizedString
                raise _fail(t, "missing required attribute; expected a type name", "name")
            if name in self.types:
                raise _fail(t, "expected a unique type name: this one is defined twice", "name")
            self.types[name] = vtype
            self.limits(body, vtype)
            if vtype == "Enumeration":
                items = body.findall("Item")
                seen = set()
                for item in items:
                    if self.version != "1.0":
                        self.integer(item, "value", *self.enum_range)
                    if item.get("name") in seen:
                        raise _fail(item, "expected a unique item name in the enumeration", "name")
                    seen.add(item.get("name"))

    # -- variables

    def variables(self) -> list:
        """[(element, name, valueReference, type)] in order (FMI 2.0's indices count from 1)."""
        holder = self.root.find("ModelVariables")
        out = []
        names: dict[str, object] = {}
        vrs: dict[tuple, object] = {}
        for v in (holder if holder is not None else []):
            if not isinstance(v.tag, str):
                continue
            if self.fmi3:
                if v.tag not in _FMI3_TYPES:
                    raise _fail(v, f"expected a variable element ({', '.join(_FMI3_TYPES)})")
                body, vtype = v, v.tag
            else:
                if v.tag != "ScalarVariable":
                    raise _fail(v, "expected ScalarVariable elements only")
                typed = [c for c in v if isinstance(c.tag, str) and c.tag in _SCALAR_TYPES]
                if len(typed) != 1:
                    raise _fail(v, f"expected one type element ({', '.join(_SCALAR_TYPES)}), found {len(typed)}")
                body, vtype = typed[0], typed[0].tag
            name = v.get("name")
            if not name:
                raise _fail(v, "expected a variable name", "name")
            aliases = [a for a in v.iterfind("Alias")] if self.fmi3 else []
            for el, n in [(v, name)] + [(a, a.get("name")) for a in aliases]:
                if not n:
                    raise _fail(el, "expected an alias name", "name")
                if any(c in n for c in "\r\n\t"):
                    # FMI 2.0 2.2.9 and FMI 3.0 2.4.7.5: a name is any Unicode character but CR, LF and
                    # TAB (XML 1.0 has no other C0 control): a name is one line of a CSV header or a legend.
                    raise _fail(el, f"expected a name without a line break or a tab (FMI: any character but "
                                    f"CR, LF and TAB), got {shorten(n, 80)!r}", "name")
                if n in names and not (self.version == "1.0" and _internal(names[n]) and _internal(el)):
                    raise _fail(el, f"expected a unique variable name: {shorten(n, 80)!r} is also the name on line "
                                    f"{names[n].sourceline}", "name")
                names[n] = el
            if v.get("valueReference") is None:
                raise _fail(v, "missing required attribute; expected an unsigned 32-bit integer", "valueReference")
            vr = self.integer(v, "valueReference", 0, _VR_MAX)
            # FMI 3.0: one value reference, one variable. FMI 1.0/2.0: variables
            # of one base type (Integer and Enumeration alike) on one are aliases.
            key = (vr,) if self.fmi3 else (vr, "Integer" if vtype == "Enumeration" else vtype)
            if key in vrs and self.fmi3:
                first = vrs[key]
                raise _fail(v, f"expected a unique valueReference: {first.get('name')!r} on line {first.sourceline} "
                               "has it too (FMI 3.0 has no aliases by value reference)", "valueReference")
            vrs.setdefault(key, v)
            self.attributes(v, body, vtype)
            out.append((v, name, vr, vtype))
        return out

    def attributes(self, v, body, vtype: str) -> None:
        versions = self.version
        causality, variability = v.get("causality"), v.get("variability")
        if causality is not None and causality not in _CAUSALITIES[versions]:
            raise _fail(v, f"expected a causality: {', '.join(_CAUSALITIES[versions])}", "causality")
        if variability is not None and variability not in _VARIABILITIES[versions]:
            raise _fail(v, f"expected a variability: {', '.join(_VARIABILITIES[versions])}", "variability")
        declared = body.get("declaredType")
        if declared is not None:
            if declared not in self.types:
                raise _fail(body, "expected the name of a type in TypeDefinitions", "declaredType")
            if self.types[declared] != vtype:
                raise _fail(body, f"expected a {vtype} type: {shorten(declared, 80)} is {self.types[declared]}",
                            "declaredType")
        array = self.fmi3 and v.find("Dimension") is not None
        if vtype in ("String", "Binary") and self.fmi3:
            for s in v.iterfind("Start"):
                if vtype == "Binary":
                    text = s.get("value") or ""
                    try:
                        bytes.fromhex(text)
                    except ValueError:
                        raise _fail(s, "expected hexadecimal digits, two per byte", "value") from None
            return
        if vtype != "Clock":
            self.values(body, "start", vtype, array)
            self.limits(body, vtype, array)
        if self.fmi3:
            for d in v.iterfind("Dimension"):
                for attr in ("start", "valueReference"):
                    self.integer(d, attr, 0, _VR_MAX)
                if (d.get("start") is None) == (d.get("valueReference") is None):
                    raise _fail(d, "expected either start or valueReference")

    # -- references

    def structure(self, variables: list) -> None:
        if self.fmi3:
            by_vr = {vr: v for v, _, vr, _ in variables}
            for v, name, _, _ in variables:
                for attr in ("derivative", "clocks", "previous"):
                    self.refs(v, attr, by_vr, "the valueReference of a variable")
                for d in v.iterfind("Dimension"):
                    self.refs(d, "valueReference", by_vr, "the valueReference of a variable")
            for kind in _FMI3_STRUCTURE:
                for u in self.root.iterfind(f"ModelStructure/{kind}"):
                    if u.get("valueReference") is None:
                        raise _fail(u, "missing required attribute; expected the valueReference of a variable",
                                    "valueReference")
                    self.refs(u, "valueReference", by_vr, "the valueReference of a variable")
                    self.refs(u, "dependencies", by_vr, "valueReferences of variables")
        elif self.version == "2.0":
            by_index = {i + 1: v for i, (v, _, _, _) in enumerate(variables)}
            what = f"an index of a variable in ModelVariables (1 to {len(variables)})"
            for v, _, _, _ in variables:
                for body in v:
                    if isinstance(body.tag, str) and body.tag == "Real":
                        self.refs(body, "derivative", by_index, what)
            for kind in _FMI2_STRUCTURE:
                for u in self.root.iterfind(f"ModelStructure/{kind}/Unknown"):
                    if u.get("index") is None:
                        raise _fail(u, f"missing required attribute; expected {what}", "index")
                    self.refs(u, "index", by_index, what, f"ModelStructure/{kind}/")
                    self.refs(u, "dependencies", by_index, what, f"ModelStructure/{kind}/")

    def refs(self, el, attr: str, known: dict, what: str, prefix: str = "") -> None:
        text = el.get(attr)
        if text is None:
            return
        for tok in text.split():
            try:
                ref = parse_int(tok)
            except ValueError:
                ref = None
            if ref not in known:
                if prefix:
                    raise DescriptionProblem(f"line {el.sourceline}: {prefix}{el.tag} {attr}={shorten(text, 80)!r}: "
                                             f"{shorten(tok, 40)} is not {what}")
                raise _fail(el, f"{shorten(tok, 40)} is not {what}", attr)
