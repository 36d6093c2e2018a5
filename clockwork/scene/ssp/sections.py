"""What an SSD says besides its system, as the scene sections a TOML scene
would hold (read.py hands them to scene/load.py, which checks them as a
scene file's): the experiment (ssd:DefaultExperiment, the OSP
annotation's fixed step), the master (OMSimulator's annotation, the OSP
step, clockwork's own annotation: MasterSettings' fields, derived from the
type) and the record list (clockwork's annotation, else every output).
"""

from __future__ import annotations

from ...fmi.description import variables as variables_of
from ...engine.settings import SETTINGS as _MASTER_SETTINGS
from ...numbers import parse_int, parse_real, shorten
from .common import CW_ANNOTATION, CW_NS, OMS_NS, OSP_ANNOTATION, q
from .documents import Doc, number, tag_name
from .flatten import Flat
from .structure import Structure

# What clockwork's annotation may set: MasterSettings' fields and record keys.
_MASTER_FIELDS = tuple(_MASTER_SETTINGS)
_RECORD_KEYS = ("interval", "ticks")


class Sections:
    """The experiment, master and record sections of an SSD; `labels`:
    where each value came from, dotted key -> (file, key) (SspScene.labels)."""

    def __init__(self, structure: Structure, flat: Flat):
        self.structure = structure
        self.flat = flat
        self.warn = structure.warnings.warn
        self.labels: dict[str, tuple[str, str]] = {}

    def experiment(self, doc: Doc, root) -> tuple[dict, tuple | None]:
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
        osp = self.structure.annotation(doc, exp, OSP_ANNOTATION)
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
        for a in self.structure.annotations(exp, "com.github.ecos-platform.scenario"):
            self.warn(doc.label, doc.key(a, "type"), "ecos' scenario (timed changes of variables) is not applied")
        return out, step

    def master(self, doc: Doc, system, osp_step: tuple | None) -> dict:
        out: dict = {}
        labels: dict[str, tuple[str, str]] = {}
        oms = self.structure.annotation(doc, system, "org.openmodelica")
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
        cw = self.structure.annotation(doc, system, CW_ANNOTATION)
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

    def record(self, doc: Doc, system) -> dict:
        cw = self.structure.annotation(doc, system, CW_ANNOTATION)
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

    def default_record(self) -> list[str]:
        """Every output connector of every component (every output where a
        component declares no connectors)."""
        out = []
        for inst, elem in self.structure.instances.items():
            names = [c.name for c in elem.connectors.values()
                     if self.flat.var(("c", inst, c.name)).causality == "output"]
            if not elem.connectors:
                names = [v.name for v in elem.md.modelVariables if v.causality == "output"]
            out += [f"{inst}.{n}" for n in names
                    if variables_of(elem.md)[n].type in ("Real", "Integer", "Boolean", "Enumeration")]
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
