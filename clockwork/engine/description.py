"""What an FMU file declares, read without instantiating it.

``resolve_fmu`` finds an FMU by model name or path, ``read_fmu`` reads its
model description (cached by path, modification time and size) and checks
that it is an FMI 2.0 or 3.0 Co-Simulation FMU with a binary for this
platform. An FMI 3.0 description is seen through FMI 2.0's type names
where FMI 2.0 has the type (Float64 is "Real", Int32 "Integer"), so that
the layers above read both alike; Float32, the other integer sizes and
Binary keep their FMI 3.0 names (``INTEGER_TYPES``, ``REAL_TYPES``,
``TEXT_TYPES`` and ``types_connect`` group them); ``fmi_version`` tells
the versions apart. FMI 3.0 features the master does
not serve (clocks, arrays, scheduled execution only) are refused here with
one line naming the FMU and the feature.
"""

from __future__ import annotations

import difflib
import os
import platform
import re
import struct
import sys
import weakref
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path
from typing import Any

from ..errors import SceneError
from ..hashing import sha256_file
from ..paths import REPO, fmu_dir, in_checkout

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


def check_archive(path: Path, infos: list) -> None:
    """Refuse an archive whose unzipped size, entry count or description size is over the bounds."""
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
        names += [i.get("name") for i in tool.iterfind("EventIndicators/Indicator") if i.get("name")]
    return tuple(names)


_MD_CACHE: dict[tuple, tuple] = {}


class FmuError(SceneError):
    """A missing or unusable FMU (bad input); str() is the reason."""


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
             versions: tuple[str, ...] = ("2.0", "3.0")) -> tuple[Any, str, tuple[str, ...]]:
    """(model description, sha256, event indicators) of an FMU, cached by
    (path, mtime, size); its FMI version must be one of `versions`."""
    import fmpy

    path = Path(path).resolve()
    try:
        st = path.stat()
    except OSError as e:
        raise FmuError(f"cannot read {path}: {e.strerror}") from None
    key = (str(path), st.st_mtime_ns, st.st_size)
    hit = _MD_CACHE.get(key)
    if hit is None:
        if not zipfile.is_zipfile(path):
            raise FmuError(f"{path} is not an FMU: not a zip archive")
        try:
            with zipfile.ZipFile(path) as z:
                infos = z.infolist()
                names = {i.filename for i in infos}
                if "modelDescription.xml" not in names:
                    raise FmuError(f"{path} is not an FMU: no modelDescription.xml in the archive")
                check_archive(path, infos)
                xml = z.read("modelDescription.xml")
                # FMI 3.0 names binary folders by platform tuple (x86_64-linux), FMI 2.0 by platform (linux64).
                heads = {n: _head(z, n) for n in names
                         if n.startswith((f"binaries/{fmpy.platform}/", f"binaries/{fmpy.platform_tuple}/"))}
        except (zipfile.BadZipFile, OSError) as e:
            raise FmuError(f"{path} is not a readable FMU: {e}") from None
        try:
            md = fmpy.read_model_description(str(path), validate=False)
        except Exception as e:  # fmpy raises bare Exceptions and lxml errors
            raise FmuError(f"{path}: unreadable modelDescription.xml: {e}") from None
        if md.fmiVersion not in ("2.0", "3.0"):
            raise FmuError(f"{path}: expected an FMI 2.0 or 3.0 FMU, found FMI {md.fmiVersion}")
        if md.fmiVersion == "3.0":
            _check_fmi3(path, md, xml)
        if md.coSimulation is None:
            raise FmuError(f"{path}: expected a Co-Simulation FMU (no <CoSimulation> element)")
        ident = md.coSimulation.modelIdentifier
        if not isinstance(ident, str) or not NAME_RE.match(ident):
            # fmpy loads binaries/<platform>/<modelIdentifier>.so: a path here would load a file outside the FMU.
            raise FmuError(f"{path}: modelDescription.xml: CoSimulation modelIdentifier {ident!r}: expected a "
                           "plain name (letters, digits, underscores), the binary's file name")
        indicators = event_indicator_names(xml)
        digest = sha256_file(path)
        folder = fmpy.platform_tuple if md.fmiVersion == "3.0" else fmpy.platform
        binary = f"binaries/{folder}/{ident}{fmpy.sharedLibraryExtension}"
        problem = binary_problem(heads[binary]) if binary in heads else "missing"
        hit = (md, digest, indicators, problem, binary)
        _MD_CACHE.clear() if len(_MD_CACHE) > 256 else None
        _MD_CACHE[key] = hit
    md, digest, indicators, problem, binary = hit
    if md.fmiVersion not in versions:
        raise FmuError(f"{path}: expected an FMI {' or '.join(versions)} FMU, found FMI {md.fmiVersion}")
    if need_binary and problem == "missing":
        raise FmuError(f"{path} has no binary for this platform ({binary}); {_rebuild_advice(path)}")
    if need_binary and problem is not None:
        raise FmuError(f"{path}: {binary}: {problem}; {_rebuild_advice(path)}")
    return md, digest, indicators


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


def _check_fmi3(path: Path, md, xml: bytes) -> None:
    """Refuse what the master does not serve; rename the types it does."""
    clocks = [v.name for v in md.modelVariables if v.type == "Clock"]
    if clocks:
        raise FmuError(f"{path}: {md.modelName} uses clocks ({', '.join(clocks[:3])}"
                       f"{', ...' if len(clocks) > 3 else ''}), which the master does not support")
    if md.coSimulation is None and getattr(md, "scheduledExecution", None) is not None:
        raise FmuError(f"{path}: {md.modelName} is a Scheduled Execution FMU, which the master does not support")
    arrays = [v.name for v in md.modelVariables if v.dimensions]
    if arrays:
        raise FmuError(f"{path}: {md.modelName} has array variables ({', '.join(arrays)}), "
                       f"which the master does not support")
    intermediate = _intermediate_update_names(xml)
    for v in md.modelVariables:
        v.type = _FMI3_AS_FMI2.get(v.type, v.type)
        v.intermediateUpdate = v.name in intermediate


def type_name(md, v) -> str:
    """A variable's type as its modelDescription.xml names it (Float64, not
    Real, in an FMI 3.0 FMU)."""
    if md.fmiVersion == "3.0":
        return {fmi2: fmi3 for fmi3, fmi2 in _FMI3_AS_FMI2.items()}.get(v.type, v.type)
    return v.type


def fmi_version(md) -> int:
    """2 or 3: the major FMI version of a model description."""
    return 3 if md.fmiVersion == "3.0" else 2


def event_indicators(path: Path) -> tuple[str, ...]:
    """Names of the event-indicator outputs declared in an FMU's vendor annotation."""
    return read_fmu(path, need_binary=False)[2]


_VARIABLES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def variables(md) -> dict:
    """{name: ScalarVariable} of a model description, built once per
    description (fmpy's ModelDescription has __slots__: the table is kept
    beside it, not on it)."""
    try:
        cache = _VARIABLES.get(md)
    except TypeError:  # not weakly referenceable: build it each time
        return {v.name: v for v in md.modelVariables}
    if cache is None or len(cache) != len(md.modelVariables):
        cache = {v.name: v for v in md.modelVariables}
        _VARIABLES[md] = cache
    return cache


# The integer types and their ranges: FMI 2.0's Integer is a C int, FMI
# 3.0's sized types keep their own names (and fmi3Get/Set* functions).
_INT_RANGES = {"Integer": (-2**31, 2**31 - 1), "Int32": (-2**31, 2**31 - 1),
               **{f"Int{b}": (-2**(b - 1), 2**(b - 1) - 1) for b in (8, 16, 64)},
               **{f"UInt{b}": (0, 2**b - 1) for b in (8, 16, 32, 64)}}
INTEGER_TYPES = (*_INT_RANGES, "Enumeration")
# Float32 is a Real exchanged through fmi3Get/SetFloat32.
REAL_TYPES = ("Real", "Float32")
# Recorded as text: Binary as hexadecimal digits (FMI 3.0).
TEXT_TYPES = ("String", "Binary")
FLOAT32_MAX = 3.4028234663852886e38


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
