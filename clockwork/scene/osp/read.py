"""Read an Open Simulation Platform system structure (libcosim's
``OspSystemStructure.xml``, schema version 0.1) into the scene model: the
same components and connections a TOML scene or an SSP gives.

What is read, as libcosim reads it (docs/osp.md):

- ``Simulator``: an FMU (``source``, a path or ``file:`` URI relative to the
  file), its ``InitialValues`` (Real, Integer, Boolean, String) and its
  ``stepSize`` (libcosim steps it every k-th base step, k the whole number
  of base steps in it, at least 1);
- ``StartTime``, ``EndTime``, ``BaseStepSize`` (0.1 s where not given, as
  libcosim takes), ``Algorithm`` fixedStep;
- ``VariableConnection`` (the output end found from the FMUs' causalities),
  ``SignalConnection`` through a ``LinearTransformation`` function (one
  link with its factor and offset, as an SSP's linear transformation),
  through a ``Sum`` (one link per term into the input it feeds, the
  further terms added in the order of their indices: Link.adds) and
  ``SignalGroupConnection`` through a ``VectorSum`` (the same, element by
  element of the first ``dimension`` variables of each top-level group),
  ``VariableGroupConnection`` (the variables of two groups of the FMUs'
  ``<modelName>_OspModelDescription.xml``, pair by pair, nested groups
  first); ``powerBond`` and ``causality`` attributes (ecco's) change
  nothing in a fixed-step run.

No unit conversion on links (libcosim converts none: a note where the units
differ). What clockwork does not do is refused in one line naming the file,
the element and what was expected: the ecco algorithm, FMUs on another
machine (``proxyfmu://host``; ``proxyfmu://localhost`` runs the FMU in this
process). Per-simulator steps that differ become the components' own
steps (scene/load.py, engine/multirate.py).
"""

from __future__ import annotations

import hashlib
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import parse_qsl, unquote, urlsplit

from ...fmi.description import INTEGER_TYPES, REAL_TYPES, FmuError, read_fmu, types_connect, var_unit
from ...fmi.description import variables as variables_of
from ...engine.model_exchange import interface_of, model_exchange_problem
from ...errors import SceneError
from ...files import absent
from ...numbers import XSD_SPECIAL, parse_int, parse_real, shorten
from ..checks import SETTABLE, STRUCTURAL, Ctx, convert_value, instance_problem, read_bounded, settable_problem
from ..model import Component, Connection
from ..ssp.common import Warnings, XmlError, parse_xml
from ..ssp.documents import MAX_XML_BYTES, Doc

# the namespace of libcosim's OspSystemStructure.xsd (not the OSP annotation's of an SSP, ssp.common.OSP_NS)
SYSTEM_NS = "http://opensimulationplatform.com/MSMI/OSPSystemStructure"
ROOT = "OspSystemStructure"
OSP_FILE = "OspSystemStructure.xml"  # what libcosim reads in a folder it is given
VERSION = "0.1"
DEFAULT_BASE_STEP = 0.1  # s: libcosim's when BaseStepSize is not given
MAX_SIMULATORS = 10_000  # as an SSP's components: each is an FMU instance
MAX_SIGNALS = 100_000  # a Sum's inputs, a VectorSum's dimension: each is a connection
# libcosim's durations are whole nanoseconds (std::chrono::nanoseconds)
_NS_PER_S = 1_000_000_000
_TOP = ("StartTime", "EndTime", "BaseStepSize", "Algorithm", "Simulators", "Functions", "Connections",
        "EccoConfiguration")
_VALUE_TYPES = ("Real", "Integer", "Boolean", "String")


class OtherXml(SceneError):
    """An XML file whose root is not OspSystemStructure: `root` is its local
    name, for the caller to say what the file is instead."""

    def __init__(self, root: str, path: Path):
        super().__init__(f"root element {shorten(root, 60)}", path)
        self.root = root


@dataclass
class OspScene:
    """What an OSP system structure says; load.py makes the Scene of it (the
    fields load._load_system reads of an SspScene)."""

    name: str
    description: str
    components: dict[str, Component]
    connections: tuple[Connection, ...]
    sections: dict  # "experiment", "master", "record" tables, as a TOML scene would hold them
    sha256: str  # of the file and of the *_OspModelDescription.xml files it reads
    warnings: list[str] = field(default_factory=list)
    aliases: dict = field(default_factory=dict)  # (no system connectors in OSP)
    # simulator -> (step in s libcosim gives it, file, key), where a stepSize is given
    step_hints: dict[str, tuple[float, str, str]] = field(default_factory=dict)
    no_stop: tuple[str, str] | None = None  # (file, key) for the note that the run stops 1 s after the start
    labels: dict[str, tuple[str, str]] = field(default_factory=dict)
    # what the file's stop time and per-component steps are called, for load.py's notes and errors
    stop_term: str = "EndTime"
    stop_like: str = "as for an SSP without a stopTime (libcosim runs until it is stopped)"
    step_term: str = "Simulator stepSize"


class _Doc(Doc):
    """An OSP XML file: elements named by their local names (one namespace per file)."""

    def tag(self, el) -> str:
        return _local(el)


def _local(el) -> str:
    tag = el.tag if isinstance(el.tag, str) else "?"
    return shorten(tag.rpartition("}")[2], 100)


def _s(text: object) -> str:
    return shorten(text, 100)


@dataclass
class _Function:
    """A function of the Functions element: its kind, element, its fixed
    signal names, input count and dimension (Sum, VectorSum), and what its
    signals are connected to (signal -> (simulator, variable or variables, element))."""

    kind: str
    el: object
    ports: tuple[str, ...]
    inputs: int = 0
    dimension: int = 0
    ends: dict = field(default_factory=dict)

    def signal_names(self) -> str:
        if not self.inputs:
            return " or ".join(self.ports)
        last = f"in[{self.inputs - 1}]"
        return f"in[0]{' ... ' + last if self.inputs > 2 else ', ' + last if self.inputs == 2 else ''} or out"


@dataclass
class _Sim:
    name: str
    el: object
    fmu: Path
    md: object
    digest: str
    indicators: tuple
    interface: str | None
    groups: dict | None = None  # variable groups of its OspModelDescription, read when a connection needs them


class _Reader:
    def __init__(self, path: Path):
        self.path = path
        self.digest = hashlib.sha256()
        self.sims: dict[str, _Sim] = {}
        self.functions: dict[str, _Function] = {}
        self.links: dict[tuple[str, str], tuple] = {}  # (inst, input) -> (src inst, output, factor, offset, el)
        # (inst, input) -> the further (src inst, output) a Sum adds to its links entry, in order
        self.sums: dict[tuple[str, str], list[tuple[str, str]]] = {}
        self.values: dict[tuple[str, str], tuple] = {}  # (inst, var) -> (value, InitialValue element)
        self.labels: dict[str, tuple[str, str]] = {}
        self.warnings = Warnings()

    def warn(self, key: str, text: str, kind: str | None = None) -> None:
        self.warnings.warn(self.doc.label, key, text, kind)

    # -- the file

    def _parse(self, path: Path, noun: str, expected: str) -> _Doc:
        data = read_bounded(path, MAX_XML_BYTES, noun, expected)
        self.digest.update(f"{path}\0{len(data)}\0".encode() + data)
        try:
            root = parse_xml(data, "OSP")
        except XmlError as e:  # not XML at all (a binary file, text) says what was expected too
            raise SceneError(f"{e}; expected {expected}", path) from None
        return _Doc(str(path), path.parent, root)

    def read(self) -> OspScene:
        self.doc = doc = self._parse(self.path, "OSP system structure", "an OspSystemStructure.xml file")
        root = doc.root
        ns, _, local = root.tag[1:].partition("}") if root.tag.startswith("{") else ("", "", root.tag)
        if local != ROOT:
            raise OtherXml(local, self.path)
        if ns != SYSTEM_NS:
            raise doc.fail(root, f"expected the namespace {SYSTEM_NS} (libcosim's schema), got {_s(ns) or 'none'}")
        if root.get("version") != VERSION:
            raise doc.fail(root, f"expected version=\"{VERSION}\" (the OSP system structure libcosim reads)",
                           "version")
        top: dict[str, object] = {}
        for el in root:
            name = self._own(el)
            if name not in _TOP:
                raise doc.fail(el, f"not part of an OSP system structure; expected {', '.join(_TOP)}")
            if name in top:
                raise doc.fail(el, f"expected one {name}: line {top[name].sourceline} gives it too")
            top[name] = el
        if "Simulators" not in top:
            raise doc.fail(root, "expected a Simulators element")
        experiment = {}
        for key, tag in (("start", "StartTime"), ("stop", "EndTime")):
            if tag in top:
                experiment[key] = self._time(top[tag])
                self.labels[f"experiment.{key}"] = (doc.label, doc.key(top[tag]))
        base_el = top.get("BaseStepSize")
        if base_el is not None:
            base = self._time(base_el)
            if not base > 0:
                raise doc.fail(base_el, "expected a step > 0 s")
            self.labels["master.step"] = (doc.label, doc.key(base_el))
        else:
            base = DEFAULT_BASE_STEP
            self.labels["master.step"] = (doc.label, f"{doc.key(root)} (no BaseStepSize: libcosim's 0.1 s)")
            self.warn(doc.key(root), f"no BaseStepSize: the base step is {DEFAULT_BASE_STEP:g} s, as libcosim "
                                     "takes (--set master.step=<s> for another)")
        self._algorithm(top.get("Algorithm"), top.get("EccoConfiguration"))
        hints = self._simulators(top["Simulators"], base)
        if not self.sims:
            raise doc.fail(top["Simulators"], "expected at least one Simulator (an FMU)")
        if "Functions" in top:
            self._functions(top["Functions"])
        if "Connections" in top:
            self._connections(top["Connections"])
        components = self._components()
        connections = tuple(c for (inst, var), (src, out, factor, offset, _) in self.links.items()
                            for c in [Connection(src, out, inst, var, factor, offset)]
                            + [Connection(i, v, inst, var, adds=True) for i, v in self.sums.get((inst, var), ())])
        record = [f"{inst}.{v.name}" for inst, s in self.sims.items() for v in s.md.modelVariables
                  if v.causality == "output" and v.type in REAL_TYPES + INTEGER_TYPES + ("Boolean",)
                  and not getattr(v, "shape", None)]
        sections = {"experiment": experiment, "master": {"step": base}, "record": {"outputs": record}}
        no_stop = None if "stop" in experiment else (doc.label, doc.key(root))
        # libcosim's files are all named OspSystemStructure.xml: the folder names the system
        title = self.path.stem if self.path.stem != ROOT else (self.path.resolve().parent.name or ROOT)
        return OspScene(title, "", components, connections, sections, self.digest.hexdigest(),
                        self.warnings.lines(), {}, hints, no_stop, self.labels)

    def _own(self, el) -> str:
        """An element's local name; an element of another namespace (or a
        comment's stand-in) is refused."""
        ns, _, local = el.tag[1:].partition("}") if el.tag.startswith("{") else ("", "", el.tag)
        if ns != SYSTEM_NS:
            raise self.doc.fail(el, f"expected an element of the namespace {SYSTEM_NS}, got {_s(ns) or 'none'}")
        return local

    def _time(self, el) -> float:
        if len(el):
            raise self.doc.fail(el, "expected a number, not elements")
        try:
            x = parse_real((el.text or "").strip(), XSD_SPECIAL)
        except ValueError:
            raise self.doc.fail(el, f"expected a number (xs:double), got {_s((el.text or '').strip())!r}") from None
        if not math.isfinite(x):
            raise self.doc.fail(el, "expected a finite number")
        return x

    def _algorithm(self, el, ecco) -> None:
        doc = self.doc
        text = (el.text or "").strip() if el is not None else "fixedStep"
        if el is not None and len(el):
            raise doc.fail(el, "expected fixedStep, not elements")
        if text.lower() == "ecco":  # libcosim reads the name in any case
            raise doc.fail(el, "not supported: the ecco algorithm (libcosim's adaptive step from power bonds); "
                               "expected fixedStep")
        if text.lower() != "fixedstep":
            raise doc.fail(el, f"expected fixedStep (or ecco, which clockwork does not run), got {_s(text)!r}")
        if ecco is not None:
            self.warn(doc.key(ecco), "the ecco algorithm's settings are not used by fixedStep (nor by libcosim)")

    # -- simulators

    def _simulators(self, holder, base: float) -> dict[str, tuple[float, str, str]]:
        doc = self.doc
        hints = {}
        for el in holder:
            if self._own(el) != "Simulator":
                raise doc.fail(el, "expected Simulator elements only")
            name = el.get("name")
            if not name:
                raise doc.fail(el, "expected a simulator name", "name")
            problem = instance_problem(name)
            if problem:
                raise doc.fail(el, problem.replace("instance name", "simulator name"), "name")
            if name in self.sims:
                raise doc.fail(el, f"expected a unique simulator name: line {self.sims[name].el.sourceline} "
                                   "names one so too", "name")
            if len(self.sims) >= MAX_SIMULATORS:
                raise doc.fail(el, f"more than {MAX_SIMULATORS} simulators (FMU instances): not read")
            if el.get("source") is None:
                raise doc.fail(el, "missing required attribute; expected the FMU's path", "source")
            fmu = self._resolve(el, "source")
            try:
                md, digest, indicators = read_fmu(fmu)
            except FmuError as e:
                raise doc.fail(el, str(e), "source") from None
            interface = None
            if md.coSimulation is None:  # libcosim runs Co-Simulation only; clockwork wraps Model Exchange
                try:
                    if interface_of(md, None) == "model-exchange":
                        indicators = ()  # located inside the wrapper
                        problem = model_exchange_problem(md)
                        if problem:
                            raise SceneError(problem)
                except SceneError as e:
                    raise doc.fail(el, e.detail, "source") from None
            sim = _Sim(name, el, fmu, md, digest, indicators, interface)
            self.sims[name] = sim
            if el.get("stepSize") is not None:
                hints[name] = self._step(el, base)
            for child in el:
                if self._own(child) != "InitialValues":
                    raise doc.fail(child, "expected InitialValues only inside a Simulator")
                self._initial_values(sim, child)
        return hints

    def _step(self, el, base: float) -> tuple[float, str, str]:
        """The step libcosim gives a simulator of this stepSize: the whole
        number of base steps in it (nanoseconds, truncated), at least one."""
        doc = self.doc
        step = _number(doc, el, "stepSize")
        if not step > 0:
            raise doc.fail(el, "expected a step > 0 s", "stepSize")
        step_ns, base_ns = int(step * _NS_PER_S), max(1, int(base * _NS_PER_S))
        k = max(1, step_ns // base_ns)
        effective = k * base
        if step_ns != k * base_ns:  # in whole nanoseconds, as libcosim tells (3e-4 s is 3 steps of 1e-4 s)
            self.warn(doc.key(el, "stepSize"), f"libcosim steps {_s(el.get('name'))} every {k} base step"
                      f"{'s' * (k != 1)} ({effective:g} s), not every {step:g} s; so does clockwork",
                      "a stepSize that is no whole number of base steps (libcosim rounds it down)")
        return effective, doc.label, doc.key(el, "stepSize")

    def _resolve(self, el, attr: str) -> Path:
        """The file a source names: a path relative to the file, or a file: URI."""
        doc = self.doc
        uri = el.get(attr)
        try:
            parts = urlsplit(uri)
        except ValueError:
            raise doc.fail(el, "expected a path relative to the file, or a file: URI", attr) from None
        if parts.scheme.lower() == "proxyfmu":
            # libcosim runs such an FMU in a process of its own (proxyfmu://host[:port]?file=<path or file: URI>);
            # on this machine it is the same FMU, run here in clockwork's process
            host = (parts.hostname or "").lower()
            given = [v for k, v in parse_qsl(parts.query, keep_blank_values=True) if k == "file"]
            if host not in ("localhost", "127.0.0.1", "::1"):
                raise doc.fail(el, f"expected proxyfmu://localhost: {_s(parts.netloc) or 'no host'} names another "
                                   "machine (libcosim's remote FMUs), which clockwork does not reach", attr)
            if len(given) != 1 or not given[0]:
                raise doc.fail(el, "expected one file=<path> in the proxyfmu URI", attr)
            self.warn(self.doc.key(el, attr), "a proxyfmu FMU runs in clockwork's process (libcosim's runs in a "
                                              "process of its own): the same numbers",
                      "proxyfmu FMUs run in this process")
            parts = urlsplit(given[0])
        if len(parts.scheme) == 1 or re.match(r"/?[A-Za-z]:[/\\]", parts.path):
            raise doc.fail(el, "expected a path relative to the file: this is a Windows drive path", attr)
        if parts.scheme not in ("", "file"):
            raise doc.fail(el, f"the URI scheme {_s(parts.scheme)}: is not supported; expected a path relative to "
                               "the file, a file: URI or proxyfmu://localhost?file=<path>", attr)
        if parts.query or parts.fragment or not parts.path:
            raise doc.fail(el, "expected a path (without query or fragment)", attr)
        if parts.netloc and not (parts.scheme == "file" and parts.netloc.lower() == "localhost"):
            raise doc.fail(el, f"expected a file on this machine: {_s(parts.netloc)} names another host", attr)
        rel = unquote(parts.path)
        if "\0" in rel:
            raise doc.fail(el, "expected a path without a NUL character", attr)
        p = Path(rel)
        p = p if p.is_absolute() else self.path.parent / p
        try:
            found = p.is_file()
        except OSError as e:
            raise doc.fail(el, f"cannot read {shorten(p, 300)}: {e.strerror}", attr) from None
        if not found:
            raise doc.fail(el, f"{shorten(p, 300)}: {absent(p, 'an FMU file')}", attr)
        return p

    def _initial_values(self, sim: _Sim, holder) -> None:
        doc = self.doc
        variables = variables_of(sim.md)
        for el in holder:
            if self._own(el) != "InitialValue":
                raise doc.fail(el, "expected InitialValue elements only")
            name = el.get("variable")
            if not name:
                raise doc.fail(el, "expected the name of a variable", "variable")
            v = variables.get(name)
            if v is None:
                raise doc.fail(el, f"{sim.name} ({sim.md.modelName}) has no variable {_s(name)}", "variable")
            typed = list(el)
            if len(typed) != 1 or self._own(typed[0]) not in _VALUE_TYPES:
                raise doc.fail(el, "expected one value element: Real, Integer, Boolean or String")
            t = typed[0]
            kind = self._own(t)
            text = t.get("value")
            if text is None:
                raise doc.fail(t, "missing required attribute", "value")
            want = {"Integer": INTEGER_TYPES, "Real": REAL_TYPES}.get(kind, (kind,))
            if v.type not in want:
                raise doc.fail(t, f"type mismatch: the value is {kind}, {sim.md.modelName}.{_s(name)} is {v.type}")
            if kind == "Real":
                value: object = _number(doc, t, "value")
            elif kind == "Integer":
                try:
                    value = parse_int(text.strip())
                except ValueError:
                    raise doc.fail(t, "expected an integer", "value") from None
            elif kind == "Boolean":
                if text.strip() not in ("true", "false", "1", "0"):
                    raise doc.fail(t, "expected true, false, 1 or 0", "value")
                value = text.strip() in ("true", "1")
            else:
                value = text
            if v.causality == "structuralParameter":
                raise doc.fail(el, f"{sim.md.modelName}.{_s(name)} {STRUCTURAL}", "variable")
            problem = settable_problem(v)
            if problem:
                raise doc.fail(el, f"expected {SETTABLE}: {sim.md.modelName}.{_s(name)} is "
                                   f"{'an' if v.causality[0] in 'aeiou' else 'a'} {v.causality} ({problem})",
                               "variable")
            key = doc.key(el, "variable")
            value = convert_value(Ctx(self.path, {}), f"{key} ({sim.name}.{_s(name)})", value, v, sim.md)
            old = self.values.get((sim.name, name))
            if old is not None and old[0] != value:
                raise doc.fail(el, f"expected each variable once: line {old[1].sourceline} gives it another value "
                                   "(which one is meant is not said)", "variable")
            self.values[(sim.name, name)] = (value, el)

    # -- functions

    def _functions(self, holder) -> None:
        doc = self.doc
        for el in holder:
            kind = self._own(el)
            name = el.get("name")
            if not name:
                raise doc.fail(el, "expected a function name", "name")
            if name in self.functions or name in self.sims:
                raise doc.fail(el, "expected a unique name: a simulator or another function has this name", "name")
            if kind == "LinearTransformation":
                _number(doc, el, "factor", 1.0)
                _number(doc, el, "offset", 0.0)
                self.functions[name] = _Function(kind, el, ("in", "out"))
            elif kind == "Sum":
                n = _count(doc, el, "inputCount")
                self.functions[name] = _Function(kind, el, ("out",), n)
            elif kind == "VectorSum":
                n = _count(doc, el, "inputCount")
                self.functions[name] = _Function(kind, el, ("out",), n, _count(doc, el, "dimension"))
            else:
                raise doc.fail(el, "not an OSP function; expected LinearTransformation, Sum or VectorSum")

    # -- connections

    def _connections(self, holder) -> None:
        doc = self.doc
        for el in holder:
            kind = self._own(el)
            if kind == "VariableConnection":
                a, b = self._pair(el, "Variable")
                self._connect(el, a, b)
            elif kind == "VariableGroupConnection":
                a, b = self._pair(el, "VariableGroup")
                for x, y in self._group_pairs(el, a, b):
                    self._connect(el, x, y)
            elif kind in ("SignalConnection", "SignalGroupConnection"):
                group = kind == "SignalGroupConnection"
                var_tag, sig_tag = ("VariableGroup", "SignalGroup") if group else ("Variable", "Signal")
                ends = {self._own(c): c for c in el}
                if len(el) != 2 or set(ends) != {var_tag, sig_tag}:
                    raise doc.fail(el, f"expected one {var_tag} and one {sig_tag}")
                sig = ends[sig_tag]
                fname, port = sig.get("function"), sig.get("name")
                if fname is None or port is None:
                    raise doc.fail(sig, "expected the attributes function and name")
                f = self.functions.get(fname)
                if f is None:
                    raise doc.fail(sig, f"no function named {_s(fname)}; functions: "
                                        f"{_s(', '.join(self.functions) or 'none')}", "function")
                if group != (f.kind == "VectorSum"):
                    raise doc.fail(el, f"{_s(fname)} is {_article(f.kind)} {f.kind}: expected a "
                                       f"{'SignalGroupConnection' if f.kind == 'VectorSum' else 'SignalConnection'}")
                if port not in f.ports and not (f.inputs and _input_index(port, f.inputs) is not None):
                    raise doc.fail(sig, f"{_s(fname)} has no signal{' group' * group} {_s(port)}; expected "
                                        f"{f.signal_names()}", "name")
                if port in f.ends:
                    raise doc.fail(el, f"expected one connection to {_s(fname)}:{_s(port)}: line "
                                       f"{f.ends[port][2].sourceline} connects it too")
                if group:
                    sim, gname, gel = self._group_end(ends[var_tag])
                    f.ends[port] = (sim.name, self._vector(el, f, (sim, gname, gel)), el)
                else:
                    sim, var = self._endpoint(ends[var_tag])
                    f.ends[port] = (sim, var, el)
            else:
                raise doc.fail(el, "expected VariableConnection, VariableGroupConnection, SignalConnection or "
                                   "SignalGroupConnection")
        for fname, f in self.functions.items():
            wanted = list(f.ports) if not f.inputs else [f"in[{i}]" for i in range(f.inputs)] + ["out"]
            missing = next((p for p in wanted if p not in f.ends), None)
            if missing is not None:  # libcosim: "Missing expected connection"
                raise doc.fail(f.el, f"expected a {'SignalGroupConnection' if f.dimension else 'SignalConnection'} "
                                     f"to {_s(fname)}:{missing} (libcosim needs every signal of a function)")
            if f.kind == "LinearTransformation":
                (si, sv, sel), (di, dv, del_) = f.ends["in"], f.ends["out"]
                self._check_ends(f, fname, [(si, sv, sel, "in")], (di, dv, del_))
                factor, offset = _number(doc, f.el, "factor", 1.0), _number(doc, f.el, "offset", 0.0)
                self._link(del_, (si, sv), (di, dv), factor, offset)
                continue
            ins = [f.ends[f"in[{i}]"] for i in range(f.inputs)]
            out = f.ends["out"]
            # a Sum is a VectorSum of dimension 1: element j of every input adds into element j of the output
            for j in range(f.dimension or 1):
                terms = [(i, v if not f.dimension else v[j], e, p) for (i, v, e), p in
                         zip(ins, (f"in[{k}]" for k in range(f.inputs)))]
                dst = (out[0], out[1] if not f.dimension else out[1][j])
                self._check_ends(f, fname, terms, (dst[0], dst[1], out[2]))
                self._link(out[2], (terms[0][0], terms[0][1]), dst, 1.0, 0.0)
                self.sums[dst] = [(i, v) for i, v, _, _ in terms[1:]]

    def _vector(self, el, f, end) -> list[str]:
        """The first `dimension` variables of a VectorSum's variable group (libcosim adds those)."""
        sim, name, gel = end
        found = self._groups(sim, gel)["top"].get(name)
        if found is None:  # libcosim's VectorSum looks among the top-level groups only
            raise self.doc.fail(gel, f"{_s(sim.md.modelName)}_OspModelDescription.xml has no top-level variable "
                                     f"group {_s(name)} (a VectorSum takes those, as libcosim does)", "name")
        group = found[0]
        refs = [c.get("ref") for c in group if _local(c) == "Variable"]
        if len(refs) < f.dimension:
            raise self.doc.fail(el, f"dimension mismatch: {_s(f.el.get('name'))} adds vectors of dimension "
                                    f"{f.dimension}, {_s(end[0].name)}'s variable group {_s(end[1])} has "
                                    f"{len(refs)} variable{'s' * (len(refs) != 1)}")
        if len(refs) > f.dimension:
            self.warn(self.doc.key(el), f"{_s(end[0].name)}'s variable group {_s(end[1])} has {len(refs)} "
                      f"variables; {_s(f.el.get('name'))} (dimension {f.dimension}) takes the first "
                      f"{f.dimension}, as libcosim does", "variable groups longer than a VectorSum's dimension")
        return refs[:f.dimension]

    def _check_ends(self, f, fname: str, ins: list, out: tuple) -> None:
        """The function's inputs come from Real outputs, its output goes to a Real input."""
        for inst, var, cel, port in ins:
            self._check_end(f, fname, inst, var, cel, port, "output")
        self._check_end(f, fname, *out, "out", "input")

    def _check_end(self, f, fname: str, inst: str, var: str, cel, port: str, role: str) -> None:
        v = variables_of(self.sims[inst].md)[var]
        if v.causality != role:
            raise self.doc.fail(cel, f"expected an {role} at {_s(fname)}:{port}: {_s(inst + '.' + var)} is "
                                     f"{_article(v.causality)} {v.causality}")
        if v.type not in REAL_TYPES:
            raise self.doc.fail(cel, f"{_article(f.kind)} {f.kind} takes and gives Real values; "
                                     f"{_s(inst + '.' + var)} is {v.type}")
        if getattr(v, "shape", None):
            raise self.doc.fail(cel, "not supported: FMI 3.0 arrays at a function's signal")

    def _pair(self, el, tag: str) -> tuple[tuple[str, str], tuple[str, str]]:
        ends = list(el)
        if len(ends) != 2 or any(self._own(c) != tag for c in ends):
            raise self.doc.fail(el, f"expected two {tag} elements")
        for c in ends:
            causality = c.get("causality")
            if causality is not None and causality not in ("input", "output"):
                raise self.doc.fail(c, "expected input or output", "causality")
        if tag == "Variable":
            return self._endpoint(ends[0]), self._endpoint(ends[1])
        return self._group_end(ends[0]), self._group_end(ends[1])

    def _simulator(self, el) -> _Sim:
        name = el.get("simulator")
        if name is None:
            raise self.doc.fail(el, "missing required attribute; expected a simulator's name", "simulator")
        sim = self.sims.get(name)
        if sim is None:
            raise self.doc.fail(el, f"no simulator named {_s(name)}; simulators: "
                                    f"{_s(', '.join(self.sims))}", "simulator")
        return sim

    def _endpoint(self, el) -> tuple[str, str]:
        sim = self._simulator(el)
        var = el.get("name")
        if var is None:
            raise self.doc.fail(el, "missing required attribute; expected a variable's name", "name")
        if var not in variables_of(sim.md):
            raise self.doc.fail(el, f"{sim.name} ({sim.md.modelName}) has no variable {_s(var)}", "name")
        return sim.name, var

    def _connect(self, el, a: tuple[str, str], b: tuple[str, str]) -> None:
        """A link between two variables, the output end found from their
        causalities (libcosim: a's if a is an output, else b's)."""
        va, vb = (variables_of(self.sims[i].md)[v] for i, v in (a, b))
        if va.causality == "output" and vb.causality == "output":
            raise self.doc.fail(el, f"expected an output connected to an input: {_s(a[0] + '.' + a[1])} and "
                                    f"{_s(b[0] + '.' + b[1])} are both outputs")
        src, dst = (a, b) if va.causality == "output" else (b, a)
        vs, vd = (va, vb) if src is a else (vb, va)
        if vs.causality != "output":
            raise self.doc.fail(el, f"expected an output at one end: {_s(a[0] + '.' + a[1])} is "
                                    f"{_article(va.causality)} {va.causality}, {_s(b[0] + '.' + b[1])} "
                                    f"{_article(vb.causality)} {vb.causality}")
        if vd.causality != "input":
            raise self.doc.fail(el, f"expected an input at the other end: {_s(dst[0] + '.' + dst[1])} is "
                                    f"{_article(vd.causality)} {vd.causality}")
        if not types_connect(vs.type, vd.type):
            raise self.doc.fail(el, f"type mismatch: {_s(src[0] + '.' + src[1])} is {vs.type}, "
                                    f"{_s(dst[0] + '.' + dst[1])} is {vd.type}")
        if getattr(vs, "shape", None) or getattr(vd, "shape", None):
            raise self.doc.fail(el, "not supported: links of FMI 3.0 arrays in an OSP system structure")
        su, du = var_unit(vs), var_unit(vd)
        if su != du:
            self.warn(self.doc.key(el), f"{_s(src[0] + '.' + src[1])} is in {_s(su or 'no unit')}, "
                      f"{_s(dst[0] + '.' + dst[1])} in {_s(du or 'no unit')}: the value passes unconverted, as "
                      "libcosim passes it", "links between variables of different units (passed unconverted)")
        self._link(el, src, dst, 1.0, 0.0)

    def _link(self, el, src, dst, factor: float, offset: float) -> None:
        old = self.links.get(dst)
        if old is not None:
            raise self.doc.fail(el, f"input {_s(dst[0] + '.' + dst[1])} is fed twice: line {old[4].sourceline} "
                                    f"feeds it {_s(old[0] + '.' + old[1])}")
        self.links[dst] = (src[0], src[1], factor, offset, el)

    # -- variable groups

    def _group_end(self, el) -> tuple[_Sim, str, object]:
        sim = self._simulator(el)
        name = el.get("name")
        if name is None:
            raise self.doc.fail(el, "missing required attribute; expected a variable group's name", "name")
        return sim, name, el

    def _groups(self, sim: _Sim, el) -> dict:
        """The simulator's variable groups: name -> (element, its doc), the
        top-level ones and, by name where unique, the nested ones."""
        if sim.groups is not None:
            return sim.groups
        file = f"{sim.md.modelName}_OspModelDescription.xml"
        where = next((p for p in (sim.fmu.parent / file, self.path.parent / file) if p.exists()), None)
        if where is None:
            raise self.doc.fail(el, f"no {_s(file)} beside {_s(sim.fmu.name)} or this file: expected one to define "
                                    f"the variable groups of {_s(sim.name)}")
        mdoc = self._parse(where, "OSP model description", "an *_OspModelDescription.xml file")
        if _local(mdoc.root) != "OspModelDescription":
            raise mdoc.fail(mdoc.root, "expected the root element OspModelDescription")
        holders = [c for c in mdoc.root if isinstance(c.tag, str) and _local(c) == "VariableGroups"]
        if len(holders) > 1:
            raise mdoc.fail(holders[1], "expected one VariableGroups element")
        top: dict[str, tuple] = {}
        nested: dict[str, list] = {}
        variables = variables_of(sim.md)
        stack = [(g, 0) for g in reversed(list(holders[0]))] if holders else []
        while stack:
            g, depth = stack.pop()
            name = g.get("name")
            if not name:
                raise mdoc.fail(g, "expected a variable group name", "name")
            if depth == 0:
                if name in top:
                    raise mdoc.fail(g, f"expected a unique group name: line {top[name][0].sourceline} has it too",
                                    "name")
                top[name] = (g, mdoc)
            else:
                nested.setdefault(name, []).append((g, mdoc))
            for c in g:
                if _local(c) == "Variable":
                    ref = c.get("ref")
                    if ref is None:
                        raise mdoc.fail(c, "missing required attribute; expected a variable's name", "ref")
                    if ref not in variables:
                        raise mdoc.fail(c, f"{sim.md.modelName} has no variable {_s(ref)}", "ref")
            stack += [(c, depth + 1) for c in reversed(list(g)) if _local(c) != "Variable"]
        sim.groups = {"top": top, "nested": nested}
        return sim.groups

    def _group(self, end: tuple) -> tuple:
        sim, name, el = end
        groups = self._groups(sim, el)
        found = groups["top"].get(name)
        if found is None:
            found = groups["nested"].get(name, [])
            if len(found) > 1:
                raise self.doc.fail(el, f"{_s(sim.name)} has {len(found)} nested variable groups named {_s(name)}: "
                                        "which one is meant is not said", "name")
            if not found:
                names = ", ".join(list(groups["top"])[:20])
                raise self.doc.fail(el, f"{_s(sim.md.modelName)}_OspModelDescription.xml has no variable group "
                                        f"{_s(name)}; groups: {_s(names or 'none')}", "name")
            found = found[0]
        return found

    def _group_pairs(self, el, a: tuple, b: tuple) -> list[tuple[tuple[str, str], tuple[str, str]]]:
        """The variable pairs of two groups: their nested groups pair by pair
        (in order, depth first), then their own variables pair by pair."""
        out = []
        stack = [(self._group(a), self._group(b))]
        while stack:
            (ga, da), (gb, db) = stack.pop()
            subs = [[c for c in g if _local(c) != "Variable"] for g in (ga, gb)]
            refs = [[c.get("ref") for c in g if _local(c) == "Variable"] for g in (ga, gb)]
            for what, (x, y) in (("nested groups", subs), ("variables", refs)):
                if len(x) != len(y):
                    raise self.doc.fail(el, f"the variable groups differ in size: {_s(a[0].name)}'s "
                                            f"{_s(ga.get('name'))} has {len(x)} {what}, {_s(b[0].name)}'s "
                                            f"{_s(gb.get('name'))} {len(y)}")
            pairs = [((a[0].name, x), (b[0].name, y)) for x, y in zip(*refs)]
            stack += [((x, da), (y, db)) for x, y in reversed(list(zip(*subs)))]
            out.append(pairs)
        return [p for pairs in out for p in pairs]

    # -- components

    def _components(self) -> dict[str, Component]:
        params: dict[str, dict] = {name: {} for name in self.sims}
        for (inst, var), (value, el) in self.values.items():
            if (inst, var) in self.links:
                self.warn(self.doc.key(el, "variable"), f"{_s(inst + '.' + var)} is a connected input; its "
                          "connection wins over this value", "initial values of connected inputs (the connection "
                                                             "wins)")
                continue
            params[inst][var] = value
        return {name: Component(name, s.fmu, s.digest, s.md, params[name], s.indicators, interface=s.interface)
                for name, s in self.sims.items()}


def _article(word: str) -> str:
    return "an" if word[:1] in "aeiou" else "a"


def _count(doc: Doc, el, attr: str) -> int:
    """A required xs:positiveInteger attribute (a Sum's inputCount, a VectorSum's dimension)."""
    text = el.get(attr)
    if text is None:
        raise doc.fail(el, "missing required attribute; expected a whole number >= 1", attr)
    try:
        n = parse_int(text.strip())
    except ValueError:
        n = 0
    if not 1 <= n <= MAX_SIGNALS:
        raise doc.fail(el, f"expected a whole number from 1 to {MAX_SIGNALS}, got {_s(text)!r}", attr)
    return n


def _input_index(port: str, count: int) -> int | None:
    """i where `port` is in[i] of a function of `count` inputs, else None."""
    m = re.fullmatch(r"in\[(0|[1-9][0-9]{0,9})\]", port)
    return int(m.group(1)) if m and int(m.group(1)) < count else None


def _number(doc: Doc, el, attr: str, default: float | None = None) -> float:
    text = el.get(attr)
    if text is None:
        if default is None:
            raise doc.fail(el, "missing required attribute; expected a number", attr)
        return default
    try:
        x = parse_real(text.strip(), XSD_SPECIAL)
    except ValueError:
        raise doc.fail(el, "expected a number (xs:double)", attr) from None
    if not math.isfinite(x):
        raise doc.fail(el, "expected a finite number", attr)
    return x


def read_osp(path: str | Path) -> OspScene:
    """An OspSystemStructure.xml, read; raises SceneError (OtherXml where the
    file is XML of another root)."""
    return _Reader(Path(path)).read()
