"""What an FMU file declares, read without instantiating it.

``resolve_fmu`` finds an FMU by model name or path, ``read_fmu`` reads its
model description (cached by path, modification time and size) and checks
that it is an FMI 2.0 Co-Simulation FMU with a binary for this platform.
"""

from __future__ import annotations

import difflib
import re
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path
from typing import Any

from ..errors import SceneError
from ..hashing import sha256_file
from ..paths import REPO, fmu_dir, in_checkout

NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def event_indicator_names(xml: bytes) -> tuple[str, ...]:
    """Outputs that a modelDescription.xml declares as event indicators (the
    annotation clockwork: FMI 2.0's VendorAnnotations/Tool, FMI 3.0's
    Annotations/Annotation)."""
    try:
        root = ET.fromstring(xml)
    except ET.ParseError:
        return ()
    names = []
    for tool in root.iterfind("VendorAnnotations/Tool"):
        if tool.get("name") == "clockwork":
            names += [i.get("name") for i in tool.iterfind("EventIndicators/Indicator") if i.get("name")]
    for note in root.iterfind("Annotations/Annotation"):
        if note.get("type") == "clockwork":
            names += [i.get("name") for i in note.iterfind("EventIndicators/Indicator") if i.get("name")]
    return tuple(names)


_MD_CACHE: dict[tuple, tuple] = {}


class FmuError(SceneError):
    """A missing or unusable FMU (bad input); str() is the reason."""


def resolve_fmu(spec: str, base_dir: Path | None = None) -> Path:
    """A model name -> <fmu_dir>/<name>.fmu; a path ending .fmu -> relative to base_dir."""
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
    d = fmu_dir()
    p = d / f"{spec}.fmu"
    if p.is_file():
        return p
    known = sorted(q.stem for q in d.glob("*.fmu")) if d.is_dir() else []
    close = difflib.get_close_matches(spec, known, n=1)
    hint = f" (did you mean {close[0]}?)" if close else ""
    if in_checkout():
        src = f"; there is no src_c/models/{spec} either" if not (REPO / "src_c" / "models" / spec).is_dir() else ""
        where = f"else <repo>/fmus; build the FMUs with `cmake --build build`{src}"
    else:
        where = f"else the FMUs installed with clockwork: {', '.join(known) or 'none'}"
    raise FmuError(f"no FMU named {spec}{hint}: looked for {p} (the FMU directory is $CLOCKWORK_FMU_DIR, {where})")


def read_fmu(path: Path, need_binary: bool = True,
             versions: tuple[str, ...] = ("2.0",)) -> tuple[Any, str, tuple[str, ...]]:
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
                names = set(z.namelist())
                if "modelDescription.xml" not in names:
                    raise FmuError(f"{path} is not an FMU: no modelDescription.xml in the archive")
                xml = z.read("modelDescription.xml")
        except (zipfile.BadZipFile, OSError) as e:
            raise FmuError(f"{path} is not a readable FMU: {e}") from None
        try:
            md = fmpy.read_model_description(str(path), validate=False)
        except Exception as e:  # fmpy raises bare Exceptions and lxml errors
            raise FmuError(f"{path}: unreadable modelDescription.xml: {e}") from None
        if md.coSimulation is None:
            raise FmuError(f"{path}: expected a Co-Simulation FMU (no <CoSimulation> element)")
        indicators = event_indicator_names(xml)
        digest = sha256_file(path)
        platform = fmpy.platform_tuple if md.fmiVersion.startswith("3.") else fmpy.platform
        binary = f"binaries/{platform}/{md.coSimulation.modelIdentifier}{fmpy.sharedLibraryExtension}"
        hit = (md, digest, indicators, binary in names, binary)
        _MD_CACHE.clear() if len(_MD_CACHE) > 256 else None
        _MD_CACHE[key] = hit
    md, digest, indicators, has_binary, binary = hit
    if md.fmiVersion not in versions:
        raise FmuError(f"{path}: expected an FMI {' or '.join(versions)} FMU, found FMI {md.fmiVersion}")
    if need_binary and not has_binary:
        raise FmuError(f"{path} has no binary for this platform ({binary}); rebuild it with `cmake --build build`")
    return md, digest, indicators


def event_indicators(path: Path) -> tuple[str, ...]:
    """Names of the event-indicator outputs declared in an FMU's vendor annotation."""
    return read_fmu(path, need_binary=False)[2]


def variables(md) -> dict:
    """{name: ScalarVariable} of a model description, built once."""
    cache = getattr(md, "_cw_vars", None)
    if cache is None:
        cache = {v.name: v for v in md.modelVariables}
        try:
            md._cw_vars = cache
        except AttributeError:
            pass
    return cache


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
    return int(x) if v.type in ("Integer", "Enumeration") else float(x)
