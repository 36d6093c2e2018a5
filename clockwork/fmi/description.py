"""What an FMU file declares, read without instantiating it.

``resolve_fmu`` finds an FMU by model name or path, ``read_fmu`` reads its
model description (cached by path, modification time and size) and checks
that it is an FMI 1.0, 2.0 or 3.0 Co-Simulation FMU, or an FMI 2.0 or 3.0
Model Exchange FMU, with a binary for this platform (Co-Simulation's where
it has both). An FMI 1.0 description is completed where fmpy leaves it bare
(``_check_fmi1``): its Capabilities go into ``coSimulation``, each output's
DirectDependency into ``outputs`` (absent: every input), a causality of
"none" reads as "local", and its negated aliases and MIME type are
kept for ``fmi1_details``. An FMI 3.0 description is seen through FMI 2.0's type names
where FMI 2.0 has the type (Float64 is "Real", Int32 "Integer"), so that
the layers above read both alike; Float32, the other integer sizes and
Binary keep their FMI 3.0 names (``INTEGER_TYPES``, ``REAL_TYPES``,
``TEXT_TYPES`` and ``types_connect`` group them); ``fmi_version`` tells
the versions apart. FMI 3.0 features the master does
not serve (clocks, scheduled execution only) are refused here with
one line naming the FMU and the feature.

FMI 3.0 array variables (``<Dimension>``) are served element by element:
``variables(md)`` holds, beside each array variable, one ``ArrayElement``
per element, named as fmpy names them (``y[0]``, ``A[1,2]``: indices from
0, in FMI 3.0's row-major order). An array's shape comes from its
Dimensions: a fixed ``start``, or the start value of the structural
parameter a ``valueReference`` names (structural parameters keep their
start values: clockwork does not enter configuration mode).
"""

from __future__ import annotations

import difflib
import math
import os
import platform
import re
import struct
import sys
import weakref
import xml.etree.ElementTree as ET
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import attrs
from fmpy.model_description import ModelVariable

from ..errors import SceneError
from ..files import NotRegularFile, absent, open_regular
from ..hashing import sha256_file
from ..numbers import XSD_SPECIAL, parse_real, shorten
from ..paths import REPO, fmu_dir, in_checkout
from .clocks import ScheduledFace, clock_problem
from .description_check import FLOAT32_MAX, INT_RANGES, DescriptionProblem, check_description
from .types import INTEGER_TYPES, REAL_TYPES, TEXT_TYPES  # noqa: F401 (named here by every layer)

NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")

# Bounds checked from the zip's directory before anything is read or unzipped
# (the declared sizes bound what zipfile writes: it stops there and checks the CRC).
MAX_DESCRIPTION_BYTES = 64 * 2**20  # modelDescription.xml; ours are 20-40 KB
MAX_ENTRIES = 100_000
DEFAULT_MAX_UNZIPPED_MB = 1024  # MiB: an FMU's files, unzipped; ours are 0.2 MB. $CLOCKWORK_MAX_FMU_MB changes it


def max_unzipped_bytes() -> int:
    env = os.environ.get("CLOCKWORK_MAX_FMU_MB", "").strip()
    try:
        mb = float(env) if env else DEFAULT_MAX_UNZIPPED_MB
    except ValueError:
        mb = DEFAULT_MAX_UNZIPPED_MB
    return int(mb * 2**20) if mb > 0 else int(DEFAULT_MAX_UNZIPPED_MB * 2**20)


def check_archive(path: Path | str, infos: list) -> None:
    """Refuse an archive whose unzipped size, entry count or description size
    is over the bounds, or whose entries zipfile cannot read (encrypted, or
    compressed with a method this Python lacks). `path`: as messages name it."""
    for i in infos:
        problem = entry_problem(i)
        if problem:
            raise FmuError(f"{path}: {i.filename}: {problem}")
    if len(infos) > MAX_ENTRIES:
        raise FmuError(f"{path}: {len(infos)} entries in the archive, more than {MAX_ENTRIES}: not unzipped")
    total = sum(i.file_size for i in infos)
    limit = max_unzipped_bytes()
    if total > limit:
        raise FmuError(f"{path}: unzips to {total:,} bytes, more than the limit of {limit:,} bytes "
                       f"({limit / 2**20:g} MiB): not unzipped (set CLOCKWORK_MAX_FMU_MB to allow more)")
    md = next((i for i in infos if i.filename == "modelDescription.xml"), None)
    if md is not None and md.file_size > MAX_DESCRIPTION_BYTES:
        raise FmuError(f"{path}: modelDescription.xml is {md.file_size:,} bytes, more than "
                       f"{MAX_DESCRIPTION_BYTES:,} ({MAX_DESCRIPTION_BYTES // 2**20} MiB): not read")


# zipfile's methods, each usable where Python has its module.
_METHODS = {zipfile.ZIP_STORED: "stored", zipfile.ZIP_DEFLATED: "zlib", zipfile.ZIP_BZIP2: "bz2",
            zipfile.ZIP_LZMA: "lzma"}


def entry_problem(info: zipfile.ZipInfo) -> str | None:
    """Why zipfile cannot read an archive entry, or None."""
    if info.flag_bits & 0x1:
        return "an encrypted entry: expected an unencrypted archive"
    module = _METHODS.get(info.compress_type)
    if module is None:
        return (f"compressed with method {info.compress_type}, which zipfile cannot read; expected stored, "
                "deflate, bzip2 or lzma")
    if module != "stored":
        try:
            __import__(module)
        except ImportError:
            return f"compressed with {module}, which this Python lacks"
    return None


# The first bytes of a shared library for this platform (checked without loading it).
_ELF_MACHINES = {"x86_64": 62, "aarch64": 183, "i686": 3, "armv7l": 40}


def binary_problem(head: bytes) -> str | None:
    """Why the first 64 bytes of a binaries/<platform>/ file are not a shared
    library this process can load, or None (only Linux's ELF is checked)."""
    if not sys.platform.startswith("linux"):
        return None
    if len(head) < 20 or head[:4] != b"\x7fELF":
        return "not a shared library (no ELF header)"
    bits = {1: 32, 2: 64}.get(head[4])
    if bits != struct.calcsize("P") * 8:
        return f"an ELF file for {bits or 'unknown'}-bit machines, this is a {struct.calcsize('P') * 8}-bit process"
    e_type, e_machine = struct.unpack("<HH" if head[5] == 1 else ">HH", head[16:20])
    if e_type != 3:
        return "an ELF file that is not a shared library (ET_DYN)"
    want = _ELF_MACHINES.get(platform.machine())
    if want is not None and e_machine != want:
        return f"an ELF shared library for another processor (e_machine {e_machine}, this is {platform.machine()})"
    return None


def event_indicator_names(xml: bytes) -> tuple[str, ...]:
    """Outputs that a modelDescription.xml declares as event indicators (the
    annotation clockwork: FMI 2.0's VendorAnnotations/Tool, FMI 3.0's
    Annotations/Annotation)."""
    try:
        root = ET.fromstring(xml)
    except ET.ParseError:
        return ()
    names = []
    tools = [t for t in root.iterfind("VendorAnnotations/Tool") if t.get("name") == "clockwork"]
    tools += [t for t in root.iterfind("Annotations/Annotation") if t.get("type") == "clockwork"]
    for tool in tools:
        # Directly in the Tool, or inside its one element (clockwork's Capabilities: the schemas allow one).
        names += [i.get("name") for i in tool.iterfind(".//EventIndicators/Indicator") if i.get("name")]
        # FMI 1.0's Tool holds name-value pairs only.
        names += [a.get("value") for a in tool.iterfind("Annotation")
                  if a.get("name") == "eventIndicator" and a.get("value")]
    return tuple(names)


def declares_outputs_after_inputs(xml: bytes) -> bool:
    """Whether a modelDescription.xml says, in the annotation clockwork
    (``<Capabilities outputsAfterInputs="true"/>``, the Tool's or the
    Annotation's one element, or FMI 1.0's
    ``<Annotation name="outputsAfterInputs" value="true"/>``), that its
    outputs may be read after its inputs are set without a step between:
    what FMI 2.0 (4.2.4) and FMI 3.0's Step Mode do not allow by default.
    The project's own FMUs declare it (their runtime computes outputs on
    every get); an FMU without it never sees such a get (docs/master.md)."""
    if b"outputsAfterInputs" not in xml:
        return False
    try:
        root = ET.fromstring(xml)
    except ET.ParseError:
        return False
    tools = [t for t in root.iterfind("VendorAnnotations/Tool") if t.get("name") == "clockwork"]
    tools += [t for t in root.iterfind("Annotations/Annotation") if t.get("type") == "clockwork"]
    for tool in tools:
        if any(c.get("outputsAfterInputs") == "true" for c in tool):
            return True
        if any(a.get("name") == "outputsAfterInputs" and a.get("value") == "true"
               for a in tool.iterfind("Annotation")):
            return True
    return False


def outputs_after_inputs(path: Path) -> bool:
    """Whether the FMU at `path` declares outputs after inputs
    (declares_outputs_after_inputs; read once with its description: fmpy's
    ModelDescription has no place for it)."""
    read_fmu(path, need_binary=False)
    path = resolved(path)
    st = path.stat()
    hit = _MD_CACHE.get((str(path), st.st_mtime_ns, st.st_size))
    return bool(hit and hit[5])


_MD_CACHE: dict[tuple, tuple] = {}
_RESOLVED: dict[tuple[str, str], Path] = {}


def resolved(path) -> Path:
    """The file a path names: absolute, symbolic links followed. Remembered
    per path text and working directory: a system names one FMU file for
    each of its hundreds of components, and resolving walks every folder of
    the path."""
    text = os.fspath(path)
    key = ("" if os.path.isabs(text) else os.getcwd(), text)
    hit = _RESOLVED.get(key)
    if hit is None:
        if len(_RESOLVED) > 4096:
            _RESOLVED.clear()
        hit = _RESOLVED[key] = Path(text).resolve()
    return hit


class FmuError(SceneError):
    """A missing or unusable FMU (bad input); str() is the reason, its echoes
    of the FMU's names and values bounded (a 4 MiB attribute is no line)."""

    def __init__(self, detail: str, path: object = None, key: str | None = None):
        super().__init__(shorten(detail, 1000), path, key)


def resolve_fmu(spec: str, base_dir: Path | None = None, fmi_version: int = 2) -> Path:
    """A model name -> <fmu_dir>/<name>.fmu (the FMI 3.0 build in its fmi3/
    subfolder when fmi_version is 3); a path ending .fmu -> relative to
    base_dir, whatever its version."""
    if spec.endswith(".fmu"):
        p = Path(spec).expanduser()
        if not p.is_absolute():
            p = (base_dir or Path.cwd()) / p
        if p.is_dir():
            raise FmuError(f"{p} is a directory, not an FMU file (a zip archive)")
        if p.exists() and not p.is_file():
            raise FmuError(f"{p} {absent(p, 'an FMU file (a zip archive)')}")
        if not p.is_file():
            if Path(spec).is_absolute():
                where = ""
            elif base_dir is None:
                where = " (a relative path is taken from the current directory)"
            else:
                where = f" (a relative path in a scene is taken from the scene file's directory, {base_dir})"
            raise FmuError(f"no such FMU file: {p}{where}")
        return p
    if not NAME_RE.match(spec):
        raise FmuError("expected a model name (e.g. \"Pendulum\") or a path ending .fmu")
    d = fmu_dir(fmi_version)
    p = d / f"{spec}.fmu"
    if p.is_file():
        return p
    known = sorted(q.stem for q in d.glob("*.fmu")) if d.is_dir() else []
    close = difflib.get_close_matches(spec, known, n=1)
    hint = f" (did you mean {close[0]}?)" if close else ""
    sub = "/fmi3" if fmi_version == 3 else ""
    if in_checkout():
        src = f"; there is no src_c/models/{spec} either" if not (REPO / "src_c" / "models" / spec).is_dir() else ""
        where = f"else <repo>/fmus{sub}; build the FMUs with `cmake --build build`{src}"
    else:
        where = f"else the FMUs installed with clockwork: {', '.join(known) or 'none'}"
    raise FmuError(f"no FMU named {spec}{hint}: looked for {p} (the FMU directory is $CLOCKWORK_FMU_DIR{sub}, "
                   f"{where})")


def read_fmu(path: Path, need_binary: bool = True,
             versions: tuple[str, ...] = ("1.0", "2.0", "3.0"),
             label: str | None = None) -> tuple[Any, str, tuple[str, ...]]:
    """(model description, sha256, event indicators) of an FMU, cached by
    (path, mtime, size); its FMI version must be one of `versions`.
    `label`: what messages call the FMU (an SSP archive's member), else its path."""
    import fmpy

    path = resolved(path)
    shown = label or path
    try:
        st = path.stat()
    except OSError as e:
        raise FmuError(f"cannot read {shown}: {e.strerror}") from None
    key = (str(path), st.st_mtime_ns, st.st_size)
    hit = _MD_CACHE.get(key)
    if hit is None:
        try:
            f = open_regular(path, "an FMU (a zip archive)")
        except NotRegularFile as e:
            raise FmuError(f"{shown} {e}") from None
        except OSError as e:
            raise FmuError(f"cannot read {shown}: {e.strerror}") from None
        with f:
            if not zipfile.is_zipfile(f):
                raise FmuError(f"{shown} is not an FMU: not a zip archive")
            xml, heads, names = _read_archive(f, shown)
        try:
            check_description(xml)
        except DescriptionProblem as e:
            raise FmuError(f"{shown}: modelDescription.xml: {e}") from None
        problem = _dimension_problem(xml) if b"<Dimension" in xml else None
        if problem:  # said here: fmpy's own error would be a bare int() message
            raise FmuError(f"{shown}: modelDescription.xml: {problem}")
        try:
            md = fmpy.read_model_description(str(path), validate=False)
        except Exception as e:  # fmpy raises bare Exceptions and lxml errors
            raise FmuError(f"{shown}: unreadable modelDescription.xml: {e}") from None
        if md.fmiVersion not in ("1.0", "2.0", "3.0"):
            raise FmuError(f"{shown}: expected an FMI 1.0, 2.0 or 3.0 FMU, found FMI {md.fmiVersion}")
        if md.fmiVersion == "3.0":
            _check_fmi3(shown, md, xml)
        if md.fmiVersion == "1.0" and md.coSimulation is None:
            raise FmuError(f"{shown}: expected an FMI 1.0 Co-Simulation FMU (no <Implementation> element): "
                           "FMI 1.0 Model Exchange is not supported")
        faces = [(n, i) for n, i in (("CoSimulation", md.coSimulation), ("ModelExchange", md.modelExchange))
                 if i is not None]
        if not faces:
            raise FmuError(f"{shown}: expected a Co-Simulation or Model Exchange FMU (no <CoSimulation> or "
                           "<ModelExchange> element)")
        for face, interface in faces:
            ident = interface.modelIdentifier
            problem = identifier_problem(ident)
            if problem:
                raise FmuError(f"{shown}: modelDescription.xml: {face} modelIdentifier {shorten(ident, 100)!r}: "
                               f"{problem}")
        if md.fmiVersion == "1.0":
            _check_fmi1(shown, md, xml)
        ident = faces[0][1].modelIdentifier  # the binary of the interface it runs through by default
        indicators = event_indicator_names(xml)
        digest = sha256_file(path)
        folder = fmpy.platform_tuple if md.fmiVersion == "3.0" else fmpy.platform
        binary = f"binaries/{folder}/{ident}{fmpy.sharedLibraryExtension}"
        problem = binary_problem(heads[binary]) if binary in heads else _missing_binary(binary, ident, names)
        hit = (md, digest, indicators, problem, binary, declares_outputs_after_inputs(xml))
        _MD_CACHE.clear() if len(_MD_CACHE) > 256 else None
        _MD_CACHE[key] = hit
    md, digest, indicators, problem, binary, _ = hit
    if md.fmiVersion not in versions:
        raise FmuError(f"{shown}: expected an FMI {' or '.join(versions)} FMU, found FMI {md.fmiVersion}")
    if need_binary and problem is not None and problem.startswith("missing"):
        raise FmuError(f"{shown} has no binary for this platform ({binary}){problem[len('missing'):]}; "
                       f"{_rebuild_advice(path)}")
    if need_binary and problem is not None:
        raise FmuError(f"{shown}: {binary}: {problem}; {_rebuild_advice(path)}")
    return md, digest, indicators


def identifier_problem(ident) -> str | None:
    """Why a modelIdentifier cannot name the FMU's binary, or None. fmpy
    loads binaries/<platform>/<modelIdentifier>.so, so any file name it can
    open is accepted (a hyphen: exporters write them, and fmpy, libcosim and
    ecos load them), but nothing that leaves that folder or is no file name."""
    if not isinstance(ident, str) or not ident:
        return "expected the binary's file name (without .so), got none"
    if "/" in ident or "\\" in ident or ident in (".", ".."):
        # a path here would load a library outside the FMU
        return "expected the binary's file name (without .so), not a path"
    if any(ord(c) < 32 or ord(c) == 127 for c in ident):
        return "expected the binary's file name (without .so): it holds a control character"
    if len((ident + ".dylib").encode("utf-8", "surrogatepass")) > 255:
        return "expected the binary's file name (without .so): longer than a file name may be (255 bytes)"
    return None


def _missing_binary(binary: str, ident: str, names: set[str]) -> str:
    """"missing", and what the FMU holds instead where that helps: a
    library of another name in the platform's folder (a modelIdentifier
    that does not match the file), or the binary in another folder."""
    folder, _, file = binary.rpartition("/")
    ext = file[len(ident):]
    here = sorted(n.rpartition("/")[2] for n in names
                  if n.startswith(folder + "/") and n.endswith(ext) and n.count("/") == binary.count("/"))
    if here:
        shown = ", ".join(shorten(n, 80) for n in here[:5]) + (", ..." if len(here) > 5 else "")
        return (f"missing: {folder}/ holds {shown}, but the modelIdentifier {shorten(ident, 80)!r} in "
                f"modelDescription.xml names {shorten(file, 80)} (the binary's file name must match it)")
    elsewhere = sorted(n.rpartition("/")[0] for n in names if n.startswith("binaries/") and n.endswith("/" + file))
    if elsewhere:
        return (f"missing: {file} is in {', '.join(shorten(e, 80) for e in elsewhere[:3])}/, not in {folder}/ "
                "(the folder this FMI version and platform use)")
    return "missing"


def _read_archive(f, shown) -> tuple[bytes, dict[str, bytes], set[str]]:
    """(modelDescription.xml, {binary entry: its first 64 bytes}, every entry's name) of an open FMU
    file, its bounds checked."""
    import fmpy

    try:
        with zipfile.ZipFile(f) as z:
            infos = z.infolist()
            names = {i.filename for i in infos}
            if "modelDescription.xml" not in names:
                raise FmuError(f"{shown} is not an FMU: no modelDescription.xml in the archive")
            check_archive(shown, infos)
            xml = z.read("modelDescription.xml")
            # FMI 3.0 names binary folders by platform tuple (x86_64-linux), FMI 2.0 by platform (linux64).
            heads = {n: _head(z, n) for n in names
                     if n.startswith((f"binaries/{fmpy.platform}/", f"binaries/{fmpy.platform_tuple}/"))}
    except (zipfile.BadZipFile, OSError) as e:
        raise FmuError(f"{shown} is not a readable FMU: {e}") from None
    return xml, heads, names


def _head(z: zipfile.ZipFile, name: str) -> bytes:
    with z.open(name) as f:
        return f.read(64)


def _rebuild_advice(path: Path) -> str:
    """Rebuild advice for the project's own FMUs, the vendor's for others."""
    path = Path(path)
    own_dirs = {(REPO / "fmus").resolve(), (REPO / "fmus" / "fmi3").resolve(), fmu_dir().resolve()}
    if in_checkout() and (REPO / "src_c" / "models" / path.stem).is_dir() and path.parent.resolve() in own_dirs:
        return "rebuild it with `cmake --build build`"
    return f"this FMU cannot run here: ask its maker for a build for {_platform()}"


def _platform() -> str:
    import fmpy

    return fmpy.platform


# FMI 3.0 types that have an FMI 2.0 twin, under the FMI 2.0 names the
# layers use; the others (Float32, Int8... UInt64 but Int32, Binary) keep
# their FMI 3.0 names.
_FMI3_AS_FMI2 = {"Float64": "Real", "Int32": "Integer", "Boolean": "Boolean", "String": "String",
                 "Enumeration": "Enumeration"}


def _intermediate_update_names(xml: bytes) -> set[str]:
    """Variables of an FMI 3.0 modelDescription.xml with
    intermediateUpdate="true" (fmpy does not read the attribute)."""
    try:
        root = ET.fromstring(xml)
    except ET.ParseError:
        return set()
    return {v.get("name") for v in root.iterfind("ModelVariables/*") if v.get("intermediateUpdate") == "true"}


def _clock_attributes(path, md, xml: bytes) -> None:
    """intervalDecimal, shiftDecimal and priority of the Clock variables,
    which fmpy does not read, onto its variables (strict numbers)."""
    if b"<Clock" not in xml:
        return
    root = ET.fromstring(xml)
    by_name = {v.name: v for v in md.modelVariables}
    for el in root.iterfind("ModelVariables/Clock"):
        v = by_name.get(el.get("name"))
        if v is None:
            continue
        for attr, kind in (("intervalDecimal", "real"), ("shiftDecimal", "real"), ("priority", "int")):
            text = el.get(attr)
            if text is None:
                continue
            where = f"{path}: modelDescription.xml: Clock {v.name}: {attr}"
            if kind == "int":
                if not text.strip().isdigit():
                    raise FmuError(f"{where}={text!r}: expected a whole number >= 0")
                setattr(v, attr, int(text))
            else:
                try:
                    setattr(v, attr, parse_real(text))
                except ValueError:
                    raise FmuError(f"{where}={text!r}: expected a number") from None


def _check_clocks(path: Path | str, md) -> None:
    """Clocks and Scheduled Execution (fmi/clocks.py): refuse what the
    engine does not serve; a Scheduled Execution FMU (without Co-Simulation)
    gets a ``coSimulation`` made from its ``<ScheduledExecution>`` (no Event
    Mode, no early return), a ``clocks.ScheduledFace``, so that the layers that
    read the Co-Simulation capabilities read its own."""
    se = getattr(md, "scheduledExecution", None)
    if md.coSimulation is None and se is not None:
        cs = ScheduledFace()
        for name in ("modelIdentifier", "needsExecutionTool", "canBeInstantiatedOnlyOncePerProcess",
                     "canGetAndSetFMUstate", "canSerializeFMUstate", "providesDirectionalDerivative",
                     "providesAdjointDerivatives", "providesPerElementDependencies"):
            if hasattr(se, name):
                setattr(cs, name, getattr(se, name))
        cs.canHandleVariableCommunicationStepSize = True
        cs.hasEventMode = False
        md.coSimulation = cs
    problem = clock_problem(md)
    if problem:
        raise FmuError(f"{path}: {md.modelName}: {problem}")


def _check_fmi3(path: Path | str, md, xml: bytes) -> None:
    """Refuse what the master does not serve; rename the types it does."""
    _clock_attributes(path, md, xml)
    _check_clocks(path, md)
    _check_arrays(path, md, xml)
    intermediate = _intermediate_update_names(xml)
    for v in md.modelVariables:
        v.type = _FMI3_AS_FMI2.get(v.type, v.type)
        v.intermediateUpdate = v.name in intermediate


# FMI 1.0's Co-Simulation Capabilities that the master reads, and how
# (fmpy 0.3 reads none of them: its CoSimulation keeps the defaults).
_FMI1_CAPABILITIES = {"canHandleVariableCommunicationStepSize": "bool", "canInterpolateInputs": "bool",
                      "maxOutputDerivativeOrder": "int", "canRunAsynchronuously": "bool",
                      "canBeInstantiatedOnlyOncePerProcess": "bool", "canNotUseMemoryManagementFunctions": "bool"}
STAND_ALONE_MIME_TYPE = "application/x-fmu-sharedlibrary"


@dataclass(frozen=True)
class Fmi1Details:
    """What an FMI 1.0 description says beyond fmpy's model description."""
    negated: frozenset[str] = frozenset()  # negatedAlias variables
    mime_type: str = STAND_ALONE_MIME_TYPE  # for fmiInstantiateSlave: the tool's, for CoSimulation_Tool


_FMI1: "weakref.WeakKeyDictionary[Any, Fmi1Details]" = weakref.WeakKeyDictionary()


def _check_fmi1(path: Path, md, xml: bytes) -> None:
    """Complete an FMI 1.0 Co-Simulation description where fmpy leaves it
    bare, in the terms the layers read for FMI 2.0: the Capabilities, each
    output's DirectDependency as its ``outputs`` dependencies (no element:
    every input, FMI 1.0 Sec. 2.10), "none" as "local", and the negated
    aliases (same value reference, value negated) for ``fmi1_details``."""
    from fmpy.model_description import Unknown

    where = f"{path}: modelDescription.xml"
    root = ET.fromstring(xml)  # fmpy has parsed it already
    impl = root.find("Implementation")
    caps = impl.find("CoSimulation_StandAlone/Capabilities") if impl is not None else None
    if caps is None and impl is not None:
        caps = impl.find("CoSimulation_Tool/Capabilities")
    cs = md.coSimulation
    model = impl.find("CoSimulation_Tool/Model") if impl is not None else None
    cs.needsExecutionTool = model is not None
    cs.canGetAndSetFMUstate = cs.canSerializeFMUstate = False  # FMI 1.0 has no FMU state
    for name, kind in _FMI1_CAPABILITIES.items():
        text = (caps.get(name) if caps is not None else None)
        if text is None:
            continue
        text = text.strip()
        if kind == "bool":
            if text not in ("true", "false", "1", "0"):
                raise FmuError(f"{where}: Capabilities {name}={text!r}: expected true or false")
            setattr(cs, name, text in ("true", "1"))
        else:
            if not text.isdigit():
                raise FmuError(f"{where}: Capabilities {name}={text!r}: expected a whole number >= 0")
            setattr(cs, name, int(text))
    by_name = {v.name: v for v in md.modelVariables}
    for v in md.modelVariables:
        if v.causality == "none":  # a tool's own variable: read like a local one
            v.causality = "local"
    for e in root.iterfind("ModelVariables/ScalarVariable"):
        v = by_name.get(e.get("name"))
        typed = next((c for c in e if isinstance(c.tag, str) and c.tag in ("Real", "Integer", "Boolean", "String",
                                                                        "Enumeration")), None)
        if v is not None and v.initial is None and typed is not None and typed.get("start") is not None:
            # FMI 1.0's start: fixed (the default) or a guess; in FMI 2.0's terms, initial exact or approx
            v.initial = "approx" if typed.get("fixed", "true").strip() in ("false", "0") else "exact"
    base = {}  # (type, value reference) -> the variable that is no alias
    elements = [e for e in root.iterfind("ModelVariables/ScalarVariable") if e.get("name") in by_name]
    for e in elements:
        if e.get("alias", "noAlias") == "noAlias":
            v = by_name[e.get("name")]
            base.setdefault((v.type, v.valueReference), v)
    negated = set()
    outputs = []
    for e in elements:
        v = by_name[e.get("name")]
        if e.get("alias") == "negatedAlias":
            if v.type not in ("Real", "Integer", "Boolean"):
                raise FmuError(f"{where}: {v.name} is a negatedAlias of type {v.type}, which cannot be negated")
            negated.add(v.name)
        if e.get("alias") in ("alias", "negatedAlias"):
            v.alias = base.get((v.type, v.valueReference))
        if v.causality != "output":
            continue
        direct = e.find("DirectDependency")
        deps = None
        if direct is not None:
            deps = []
            for n in direct.iterfind("Name"):
                name = (n.text or "").strip()
                if name not in by_name:
                    raise FmuError(f"{where}: the DirectDependency of output {v.name} names {name!r}, "
                                   f"which is no variable of {md.modelName}")
                deps.append(by_name[name])
        outputs.append(Unknown(variable=v, dependencies=deps))
    md.outputs[:] = outputs
    _FMI1[md] = Fmi1Details(frozenset(negated), (model.get("type") if model is not None else None)
                            or STAND_ALONE_MIME_TYPE)


def start_problem(v) -> str | None:
    """Why the standard does not let a master set `v` before initialization,
    or None where it does. A master sets start values in the state after
    instantiation (fmi2SetupExperiment done, before
    fmi2EnterInitializationMode; FMI 3.0 before
    fmi3EnterInitializationMode; FMI 1.0 before fmiInitializeSlave), where
    FMI 2.0 (Sec. 3.2.3 and 4.2.4, the table of fmi2SetXXX) and FMI 3.0
    (Sec. 3.2.2, Instantiated) allow the variables whose variability is not
    "constant" and whose initial is "exact" or "approx" (with the defaults
    the standards give: a parameter's is "exact", an output's "calculated"),
    and inputs; FMI 1.0 the variables with a start value (``_check_fmi1``
    gives them initial "exact", or "approx" for fixed="false", a guess).
    This is what fmpy sets (``settable_in_instantiated``), libcosim and ecos
    too. A structural parameter is the caller's to refuse (configuration mode)."""
    if v.causality == "input":
        return None
    if v.causality == "independent":
        return "the independent variable (the time): no master sets it"
    if getattr(v, "variability", None) == "constant":
        return "variability=\"constant\": no master sets it"
    initial = getattr(v, "initial", None)
    if initial in ("exact", "approx"):
        return None
    initial = initial or "calculated"
    return f'initial="{initial}": the FMU computes its value'



def default_tolerance(md) -> float | None:
    """The DefaultExperiment's relative tolerance, or None (none given;
    FMI 1.0, whose Co-Simulation takes none). check_description has made
    sure it is a finite number."""
    de = md.defaultExperiment
    tol = getattr(de, "tolerance", None) if de is not None else None
    if tol in (None, "") or md.fmiVersion == "1.0":
        return None
    return parse_real(str(tol).strip(), XSD_SPECIAL)


def default_tolerance_problem(md) -> str | None:
    """What is wrong with the DefaultExperiment's tolerance as the relative
    tolerance a run would hand the FMU, or None."""
    tol = default_tolerance(md)
    if tol is not None and not 0 < tol < math.inf:
        return ("expected a finite relative tolerance > 0 (the FMU would be given it, a Model Exchange FMU "
                "integrated at it)")
    return None


def fmi1_details(md) -> Fmi1Details:
    """What ``_check_fmi1`` kept of an FMI 1.0 description: its negated
    aliases (each shares its value reference with the variable it negates,
    so its value is that variable's, negated) and the MIME type. Defaults
    for other versions and for a description that did not come from
    read_fmu (e.g. one unpickled): ask read_fmu for the file's."""
    return _FMI1.get(md, Fmi1Details())


def no_state_reason(md) -> str:
    """Why an FMU cannot save and restore its state (for the refusals of
    settings that roll every FMU back)."""
    if md.fmiVersion == "1.0":
        return "it is an FMI 1.0 FMU, which has no FMU state"
    return "its modelDescription.xml does not declare canGetAndSetFMUstate"


def type_name(md, v) -> str:
    """A variable's type as its modelDescription.xml names it (Float64, not
    Real, in an FMI 3.0 FMU)."""
    if md.fmiVersion == "3.0":
        return {fmi2: fmi3 for fmi3, fmi2 in _FMI3_AS_FMI2.items()}.get(v.type, v.type)
    return v.type


def fmi_version(md) -> int:
    """1, 2 or 3: the major FMI version of a model description."""
    return {"1.0": 1, "3.0": 3}.get(md.fmiVersion, 2)


def event_indicators(path: Path) -> tuple[str, ...]:
    """Names of the event-indicator outputs declared in an FMU's vendor annotation."""
    return read_fmu(path, need_binary=False)[2]


# One index of the variables per model description (read_fmu reads each FMU
# file once, so per FMU file): every component, connection end and check
# looks names up here. Weak keys: an index goes with its description. No
# fallback for a description that cannot be weakly referred to: a cache that
# silently never holds made loading quadratic once (fmpy's slotted class).
_VARIABLES: "weakref.WeakKeyDictionary[Any, dict]" = weakref.WeakKeyDictionary()


def variables(md) -> dict:
    """{name: variable} of a model description, built on first use and kept
    as long as the description lives: its variables and, after each FMI 3.0
    array variable, its elements (``ArrayElement``, named ``y[0]``, ``A[1,2]``)."""
    index = _VARIABLES.get(md)
    if index is None:
        index = {}
        for v in md.modelVariables:
            index[v.name] = v
            if v.shape:
                for e in array_elements(v):
                    index.setdefault(e.name, e)
        _VARIABLES[md] = index
    return index


# -- FMI 3.0 arrays ---------------------------------------------------------------

MAX_ARRAY_ELEMENTS = 100_000  # elements of one FMU's arrays: each is a variable of its own (some 40 us and 1 kB)


@attrs.define(eq=False)
class ArrayElement(ModelVariable):
    """One element of an FMI 3.0 array variable, seen as a scalar variable:
    `array` is the array variable, `index` the element's place in its
    values (row-major), `start` the element's own start value."""

    array: Any = None
    index: int = 0


def element_name(name: str, indices: tuple[int, ...]) -> str:
    """fmpy's name of an array element: ``y[0]``, ``A[1,2]`` (0-based)."""
    return f"{name}[{','.join(map(str, indices))}]"


def shape_text(shape: tuple[int, ...]) -> str:
    """A shape as the messages say it: "3" or "2x3"; a scalar is "a scalar"."""
    return "x".join(map(str, shape)) if shape else "a scalar"


def array_size(v) -> int:
    """How many values a variable holds (1 for a scalar)."""
    return math.prod(v.shape) if getattr(v, "shape", None) else 1


def array_elements(v) -> list:
    """The ArrayElements of an array variable, in row-major order (built once per variable)."""
    made = _ELEMENTS.get(v)
    if made is None:
        starts = v.start if isinstance(v.start, list) else str(v.start).split() if v.start is not None else []
        fields = {a.alias: getattr(v, a.name) for a in attrs.fields(ModelVariable) if a.init}
        made = []
        for k, idx in enumerate(_indices(v.shape)):
            e = ArrayElement(**{**fields, "name": element_name(v.name, idx), "shape": (), "dimensions": [],
                                "start": starts[k] if k < len(starts) else None})
            e.array, e.index = v, k
            made.append(e)
        _ELEMENTS[v] = made
    return made


_ELEMENTS: "weakref.WeakKeyDictionary[Any, list]" = weakref.WeakKeyDictionary()


def _indices(shape: tuple[int, ...]):
    """Index tuples of a shape in row-major order (the last index fastest)."""
    if not shape:
        return
    if len(shape) == 1:
        yield from ((i,) for i in range(shape[0]))
        return
    for i in range(shape[0]):
        for rest in _indices(shape[1:]):
            yield (i, *rest)


def element_names(v) -> list[str]:
    """A variable's element names (its own name for a scalar)."""
    return [e.name for e in array_elements(v)] if getattr(v, "shape", None) else [v.name]


def link_shape_problem(source: str, output, destination: str, input_) -> str | None:
    """Why a connection between these two variables cannot be made element
    by element (shapes that differ), or None: arrays connect to arrays of
    the same shape, scalars (and elements) to scalars."""
    a, b = tuple(getattr(output, "shape", None) or ()), tuple(getattr(input_, "shape", None) or ())
    if a == b:
        return None
    if a and b:
        return (f"the arrays differ in shape: {source} is {shape_text(a)}, {destination} is {shape_text(b)}; "
                "arrays connect to arrays of the same shape")
    if a:
        return (f"{source} is an array ({shape_text(a)}) and {destination} a scalar: connect arrays of the "
                f"same shape, or one element (e.g. {element_name(source, (0,) * len(a))})")
    return (f"{destination} is an array ({shape_text(b)}) and {source} a scalar: connect arrays of the same "
            "shape (FMI 3.0 sets an input array whole)")


def _dimension_problem(xml: bytes) -> str | None:
    """What check_description leaves to fmpy's int(): a <Dimension
    valueReference> naming a variable whose start value is no size (none,
    or not an integer >= 0), or None."""
    try:
        root = ET.fromstring(xml)
    except ET.ParseError:
        return None  # check_description has said what is wrong with the XML
    variables = list(root.iterfind("ModelVariables/*"))
    starts = {v.get("valueReference"): (v.get("name"), v.get("start")) for v in variables}
    for v in variables:
        for d in v.iterfind("Dimension"):
            vr = d.get("valueReference")
            if d.get("start") is None and vr is not None and vr.strip() in starts:
                name, size = starts[vr.strip()]
                if size is None or not re.fullmatch(r"\+?[0-9]+", size.strip()):
                    return (f"{v.get('name')}: its <Dimension> is the size {name}, whose start value "
                            f"({size if size is not None else 'none'}) is not an integer >= 0")
    return None


def _check_arrays(path: Path | str, md, xml: bytes) -> None:
    """Array variables: their Dimensions resolve to sizes, the element names
    are free, the total is bounded; a String array's start values are read
    from its <Start> elements (fmpy keeps the first only)."""
    by_vr = {v.valueReference: v for v in md.modelVariables}
    names = {v.name for v in md.modelVariables}
    arrays = [v for v in md.modelVariables if v.dimensions]
    total = 0
    for v in arrays:
        where = f"{path}: modelDescription.xml: {v.name}"
        if v.type in ("Binary", "Clock"):
            raise FmuError(f"{path}: {md.modelName} has an array of {v.type} values ({v.name}), which the master "
                           "does not support")
        for d in v.dimensions:
            if d.start is None:
                size_var = by_vr.get(d.valueReference)
                if size_var is None or size_var.causality != "structuralParameter" and \
                        size_var.variability != "constant":
                    raise FmuError(f"{where}: a <Dimension valueReference=\"{d.valueReference}\"> must name a "
                                   "structural parameter (or a constant) that gives the size")
                if size_var.type not in INTEGER_TYPES or size_var.start is None:
                    raise FmuError(f"{where}: its size comes from {size_var.name}, which is not an integer with a "
                                   "start value")
        if any(n < 0 for n in v.shape):
            raise FmuError(f"{where}: a negative array size ({shape_text(v.shape)})")
        total += array_size(v)
        if total > MAX_ARRAY_ELEMENTS:
            raise FmuError(f"{path}: {md.modelName}'s arrays hold more than {MAX_ARRAY_ELEMENTS:,} elements: "
                           "not loaded")
    if not arrays:
        return
    strings = {v.name for v in arrays if v.type == "String"}
    if strings:
        root = ET.fromstring(xml)
        for elem in root.iterfind("ModelVariables/String"):
            if elem.get("name") in strings:
                md_var = next(v for v in arrays if v.name == elem.get("name"))
                md_var.start = [s.get("value") or "" for s in elem.iterfind("Start")]
    for v in arrays:  # (the elements themselves are made later, with the types renamed)
        clash = next((n for n in (element_name(v.name, i) for i in _indices(v.shape)) if n in names), None)
        if clash is not None:
            raise FmuError(f"{path}: modelDescription.xml: the element {clash} of the array {v.name} has the "
                           "name of another variable")


# The integer types and their ranges (fmi/types.py, which the plot
# process imports without this module and fmpy).
_INT_RANGES = INT_RANGES


def int_range(var_type: str) -> tuple[int, int] | None:
    """(min, max) that an integer type can hold, or None (an Enumeration's
    items say what it takes; not an integer type)."""
    return _INT_RANGES.get(var_type)


def types_connect(output_type: str, input_type: str) -> bool:
    """Whether an output of one FMI type may feed an input of the other.
    Integers of any size and Enumerations connect either way (SSP leaves
    connections of different types to the tool; a value the input's type
    cannot hold fails the run, naming the link; the receiving FMU refuses a
    value outside its Enumeration's items), and so do Float32 and Float64."""
    if output_type == input_type:
        return True
    return any(output_type in family and input_type in family for family in (INTEGER_TYPES, REAL_TYPES))


def var_unit(v) -> str | None:
    """A variable's unit (its declared type's when it has none), or None."""
    u = v.unit or (v.declaredType.unit if v.declaredType is not None else None)
    return u or None


def var_limit(v, which: str):
    """A variable's min or max (its declared type's when it has none), or None."""
    x = getattr(v, which)
    if x is None and v.declaredType is not None:
        x = getattr(v.declaredType, which, None)
    if x is None:
        return None
    return int(x) if v.type in INTEGER_TYPES else float(x)
