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

The reading is three jobs, one module each, run in turn by ``read_ssp``:
``structure`` (the systems, components, connectors and connections as the
document nests them), ``flatten`` (the connections as the links of a flat
system) and ``parameters`` (the bindings resolved and given to the
components); ``sections`` reads the experiment, master and record
settings; ``documents`` opens and parses the files.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ...errors import SceneError
from ...files import absent
from ...hashing import sha256_file
from ..model import Component, Connection
from .common import VERSIONS, Warnings, q
from .documents import SSD_NAME, Store, unit_table
from .flatten import Aliases, Flat
from .parameters import Parameters
from .sections import Sections
from .structure import Structure

# Bounds before the work: each component is an FMU instance (a clock has 2 to 6).
MAX_COMPONENTS = 10_000  # validate and run grow linearly: docs/benchmarks.md, "Systems of many FMUs"

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


def read_ssp(path: str | Path) -> SspScene:
    """An .ssp archive or an .ssd file, read and flattened; raises SceneError."""
    path = Path(path)
    if not path.exists():
        raise SceneError(absent(path, "an .ssp archive or an .ssd file"), path)
    if path.is_dir():
        raise SceneError("is a directory, expected an .ssp archive or an .ssd file", path)
    store = Store(path)
    try:
        return _read(path, store)
    finally:
        store.close()


def _read(path: Path, store: Store) -> SspScene:
    """The three jobs in turn, on the SSD of `store`, and the sections."""
    doc = store.doc(SSD_NAME if store.zip is not None else path, "ssd:SystemStructureDescription")
    root = doc.root
    version = root.get("version")
    if version not in VERSIONS:
        raise doc.fail(root, f"expected the SSP version {' or '.join(VERSIONS)}", "version")
    warnings = Warnings()
    structure = Structure(store, warnings, MAX_COMPONENTS)
    structure.units = unit_table(doc, root.find(q("ssd", "Units")))
    system = root.find(q("ssd", "System"))
    if system is None:
        raise doc.fail(root, "expected an ssd:System element")
    top = structure.read(doc, system)
    flat = Flat(structure)
    links, fed = flat.flatten()
    parameters = Parameters(structure, flat)
    components = parameters.components(parameters.bindings(top), fed)
    connections = tuple(Connection(src[0], src[1], inst, var, factor, offset)
                        for (inst, var), (src, factor, offset) in links.items())
    sections = Sections(structure, flat)
    experiment, osp_step = sections.experiment(doc, root)
    tables = {"experiment": experiment, "master": sections.master(doc, system, osp_step),
              "record": sections.record(doc, system)}
    if "outputs" not in tables["record"]:
        tables["record"]["outputs"] = sections.default_record()
    if store.zip is not None:
        digest = sha256_file(path)  # streamed: an archive may be large
    else:
        digest = store.digest.hexdigest()
    no_stop = None
    if "stop" not in experiment:
        exp = root.find(q("ssd", "DefaultExperiment"))
        no_stop = (doc.label, doc.key(exp if exp is not None else root))
    return SspScene(root.get("name") or path.stem, system.get("description") or "", components, connections,
                    tables, digest, warnings.lines(), flat.aliases, structure.step_hints, no_stop, sections.labels)
