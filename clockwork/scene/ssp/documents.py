"""The files of an SSP, read safely: an archive's entries or the files beside
an .ssd (relative URIs resolved, zip slip refused), each XML document with
what its errors need (file, line, element, attribute), and the units and
attribute values the documents hold.
"""

from __future__ import annotations

import hashlib
import math
import posixpath
import re
import zipfile
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import unquote, urlsplit

from ...atomic import write_bytes_atomic
from ...errors import SceneError
from ...files import NotRegularFile, absent, open_regular
from ...numbers import XSD_SPECIAL, parse_int, parse_real, shorten
from ...paths import cache_root, scratch_dir
from ...fmi.description import MAX_ENTRIES, entry_problem, max_unzipped_bytes
from .common import CW_NS, NS, OMS_NS, OSP_NS, XmlError, parse_xml, q

SSD_NAME = "SystemStructure.ssd"
MAX_XML_BYTES = 16 << 20  # an SSD, SSV or SSM of more is not a description
_PREFIX = {**{v: k for k, v in NS.items()}, OSP_NS: "osp", OMS_NS: "oms", CW_NS: "cw"}
_EXPONENTS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")


def tag_name(el) -> str:
    """An element's tag as prefix:local (the SSP's and the annotations' prefixes),
    else {namespace}local, shortened."""
    ns, _, local = el.tag[1:].partition("}") if el.tag.startswith("{") else ("", "", el.tag)
    if ns in _PREFIX:
        return f"{_PREFIX[ns]}:{shorten(local, 100)}"
    return f"{{{shorten(ns, 80)}}}{shorten(local, 80)}" if ns else shorten(local, 100)


class Doc:
    """One XML file of the SSP: where it is (for messages and relative URIs) and its root."""

    def __init__(self, label: str, base: str | Path, root):
        self.label = label
        self.base = base  # folder of the file: a posix path in the archive, or a Path
        self.root = root

    def tag(self, el) -> str:
        """How messages name an element's tag."""
        return tag_name(el)

    def key(self, el, attr: str | None = None) -> str:
        tag = self.tag(el)
        name = el.get("name")
        what = f"{tag} {shorten(name, 100)!r}" if name is not None and attr != "name" else tag
        if attr is not None:
            value = el.get(attr)
            attr = shorten(attr, 100)
            what += f" {attr}" if value is None else f" {attr}={shorten(value, 100)!r}"
        return f"line {el.sourceline}: {what}"

    def fail(self, el, detail: str, attr: str | None = None) -> SceneError:
        # the values a detail echoes are shortened where it is written; this
        # bounds what was missed (a name list, a path)
        return SceneError(shorten(detail, 1000), self.label, self.key(el, attr))


class Store:
    """The files of an .ssp archive, or the directory of an .ssd file."""

    def __init__(self, path: Path):
        self.path = path
        self.zip: zipfile.ZipFile | None = None
        self.digest = hashlib.sha256()  # of the archive, or of the SSD and every file it reads
        self._fmus: dict[str, Path] = {}  # archive entry -> its copy (components may share an FMU)
        self._file = None
        if path.suffix.lower() == ".ssp":
            try:
                self._file = open_regular(path, "an SSP archive (a zip file)")
            except NotRegularFile as e:
                raise SceneError(e.detail, path) from None
            except OSError as e:
                raise SceneError(f"cannot read: {e.strerror}", path) from None
            try:
                self._open_archive(path)
            except BaseException:
                self.close()  # the archive's file, which no caller holds yet
                raise

    def _open_archive(self, path: Path) -> None:
        """The zip directory of the open archive, its entries checked."""
        if not zipfile.is_zipfile(self._file):
            raise SceneError("expected an SSP archive: a zip file with SystemStructure.ssd at its root; "
                             "this is not a zip file", path)
        try:
            self.zip = zipfile.ZipFile(self._file)
            names = self.zip.namelist()
        except (zipfile.BadZipFile, OSError, ValueError) as e:
            raise SceneError(f"expected an SSP archive: unreadable zip file ({e})", path) from None
        if len(names) > MAX_ENTRIES:
            raise SceneError(f"{len(names)} entries in the archive, more than {MAX_ENTRIES}: not read", path)
        seen = set()
        for name in names:
            parts = name.split("/")
            if "\\" in name or name.startswith("/") or ".." in parts or (parts and ":" in parts[0]):
                raise SceneError("expected a relative path inside the archive (no '..', no absolute path, "
                                 "no backslash)", path, f"archive entry {shorten(name, 100)!r}")
            if name in seen:
                # zipfile would read the last one: which file is meant is not said
                raise SceneError("expected each entry once: the archive holds two entries of this name",
                                 path, f"archive entry {shorten(name, 100)!r}")
            seen.add(name)
        self.members = seen
        if SSD_NAME not in self.members:
            raise SceneError(f"expected {SSD_NAME} at the root of the archive; entries: "
                             f"{', '.join(sorted(self.members)[:8]) or 'none'}", path)

    def close(self) -> None:
        if self.zip is not None:
            self.zip.close()
        if self._file is not None:
            self._file.close()

    def label(self, member: str) -> str:
        return f"{self.path}/{member}" if self.zip is not None else member

    def resolve(self, doc: Doc, el, attr: str) -> str | Path:
        """The file an element's URI attribute names, relative to the document
        that holds it: a relative URI reference, or a `file:` URI (RFC 8089:
        `file:/abs`, `file:///abs`, `file://localhost/abs`; `file:rel/x`, the
        relative form tools write, resolves as `rel/x`). Inside an archive
        the file must be one of its entries; beside an .ssd, any file."""
        uri = el.get(attr)
        try:
            parts = urlsplit(uri)
        except ValueError:
            parts = None
        if parts is not None and len(parts.scheme) == 1:
            raise doc.fail(el, "expected a relative path: this is a Windows drive path", attr)
        if parts is not None and parts.scheme not in ("", "file"):
            # proxyfmu:// (libcosim's and ecos' remote FMUs), http://, fmu://...
            raise doc.fail(el, f"the URI scheme {parts.scheme}: is not supported: clockwork reads the files of the "
                               "archive or beside the SSD; expected a relative path", attr)
        if parts is None or parts.query or parts.fragment or not parts.path:
            raise doc.fail(el, "expected a relative path (a URI without scheme, host, query or fragment)", attr)
        if parts.netloc and not (parts.scheme == "file" and parts.netloc.lower() == "localhost"):
            what = "another host's file" if parts.scheme == "file" else "a network path"
            raise doc.fail(el, f"expected a file on this machine: {shorten(parts.netloc, 100)} names {what}", attr)
        if parts.netloc and not parts.path.startswith("/"):
            raise doc.fail(el, "expected an absolute path after the host in a file: URI", attr)
        rel = unquote(parts.path)
        if re.match(r"/?[A-Za-z]:[/\\]", rel):  # file:///C:/x, file:C:/x
            raise doc.fail(el, "expected a relative path: this is a Windows drive path", attr)
        if "\0" in rel:
            raise doc.fail(el, "expected a path without a NUL character", attr)
        if self.zip is not None:
            if rel.startswith("/"):
                raise doc.fail(el, "expected a path inside the archive, relative to the SSD (an absolute path "
                                   "names a file outside it)", attr)
            member = posixpath.normpath(posixpath.join(doc.base, rel))
            if member == ".." or member.startswith("../"):
                raise doc.fail(el, "expected a path inside the archive: this one leaves it", attr)
            if member not in self.members:
                raise doc.fail(el, f"no such file in the archive ({shorten(member, 200)})", attr)
            return member
        p = Path(rel)
        p = p if p.is_absolute() else Path(doc.base) / p
        try:
            found = p.is_file()
        except OSError as e:  # a name too long, a loop of links
            raise doc.fail(el, f"cannot read {shorten(p, 300)}: {e.strerror}", attr) from None
        if not found:
            raise doc.fail(el, f"{shorten(p, 300)}: {absent(p, 'a regular file')}", attr)
        return p

    def entry(self, where: str) -> zipfile.ZipInfo:
        """An archive entry that zipfile can read, else SceneError naming it."""
        info = self.zip.getinfo(where)
        problem = entry_problem(info)
        if problem:
            raise SceneError(problem, self.label(where))
        return info

    def read(self, where: str | Path) -> bytes:
        if self.zip is not None:
            info = self.entry(where)
            if info.file_size > MAX_XML_BYTES:
                raise SceneError(f"{info.file_size} bytes: an SSP XML file is at most {MAX_XML_BYTES} bytes",
                                 self.label(where))
            try:
                return self.zip.read(where)
            except (zipfile.BadZipFile, OSError, ValueError) as e:
                raise SceneError(f"unreadable archive entry: {e}", self.label(where)) from None
        try:
            with open_regular(where, "an SSP XML file") as f:
                data = f.read(MAX_XML_BYTES + 1)
        except NotRegularFile as e:
            raise SceneError(e.detail, where) from None
        except OSError as e:
            raise SceneError(f"cannot read: {e.strerror}", where) from None
        if len(data) > MAX_XML_BYTES:
            raise SceneError(f"more than {MAX_XML_BYTES} bytes: not an SSP XML file", where)
        self.digest.update(f"{where}\0{len(data)}\0".encode() + data)
        return data

    def doc(self, where: str | Path, root_tag: str) -> Doc:
        label = self.label(where) if self.zip is not None else str(where)
        base = posixpath.dirname(where) if self.zip is not None else Path(where).parent
        try:
            root = parse_xml(self.read(where))
        except XmlError as e:
            raise SceneError(str(e), label) from None
        doc = Doc(label, base, root)
        prefix, local = root_tag.split(":")
        if root.tag != q(prefix, local):
            ns, _, got = root.tag[1:].partition("}") if root.tag.startswith("{") else ("", "", root.tag)
            if got == local:
                raise doc.fail(root, f"expected the namespace {NS[prefix]}, got {ns or 'none'}")
            raise doc.fail(root, f"expected the root element {root_tag} (namespace {NS[prefix]})")
        return doc

    def fmu(self, where: str | Path) -> Path:
        """A path to the FMU: the file beside the SSD, or the archive's entry
        copied once per content into the cache (the scratch folder without one)."""
        if self.zip is None:
            return Path(where)
        if where in self._fmus:
            return self._fmus[where]
        # The FMU's own files are bounded when it is read; the FMU itself, read
        # into memory here to hash and copy it, by the same unzip bound.
        size, limit = self.entry(where).file_size, max_unzipped_bytes()
        if size > limit:
            raise SceneError(f"{size:,} bytes unpacked, more than the limit of {limit:,} bytes ({limit / 2**20:g} MiB) "
                             "for an FMU: not unpacked (set CLOCKWORK_MAX_FMU_MB to allow more)", self.label(where))
        try:
            data = self.zip.read(where)
        except (zipfile.BadZipFile, OSError, ValueError) as e:
            raise SceneError(f"unreadable archive entry: {e}", self.label(where)) from None
        digest = hashlib.sha256(data).hexdigest()
        for root in (cache_root(), None):
            folder = (root / "ssp-fmus") if root is not None else (scratch_dir() / "ssp-fmus")
            target = folder / f"{digest}.fmu"
            try:
                if not (target.is_file() and target.stat().st_size == len(data)):
                    folder.mkdir(parents=True, exist_ok=True)
                    write_bytes_atomic(target, data)
                self._fmus[where] = target
                return target
            except OSError:
                if root is None:
                    raise
        raise AssertionError("unreachable")


@dataclass(frozen=True)
class Unit:
    exponents: tuple[int, ...]
    factor: float
    offset: float


def unit_table(doc: Doc, parent) -> dict[str, Unit]:
    out = {}
    if parent is None:
        return out
    for u in parent.iterfind(q("ssc", "Unit")):
        name = u.get("name")
        if not name:
            raise doc.fail(u, "expected a name", "name")
        if name in out:
            raise doc.fail(u, "expected a unique unit name: this one is defined twice", "name")
        base = u.find(q("ssc", "BaseUnit"))
        if base is None:
            raise doc.fail(u, "expected an ssc:BaseUnit child")
        exps = []
        for k in _EXPONENTS:
            try:
                exps.append(parse_int(base.get(k, "0")))
            except ValueError:
                raise doc.fail(base, "expected an integer exponent", k) from None
        factor = number(doc, base, "factor", 1.0)
        if factor == 0:
            raise doc.fail(base, "expected a factor other than 0 (a conversion divides by it)", "factor")
        out[name] = Unit(tuple(exps), factor, number(doc, base, "offset", 0.0))
    return out


def fmu_units(md) -> dict[str, Unit]:
    """The FMU's units that its BaseUnit defines in SI terms. A unit without
    one (every unit of FMI 1.0, which names units only) converts to itself
    alone, as in scene/units.py: it is left out, never taken as 1."""
    out = {}
    for u in getattr(md, "unitDefinitions", None) or []:
        b = u.baseUnit
        if b is not None:
            out[u.name] = Unit(tuple(int(getattr(b, k, 0) or 0) for k in _EXPONENTS), float(b.factor),
                                float(b.offset))
    return out


def conversion(src: str | None, dst: str | None, *tables: dict[str, Unit]) -> tuple[float, float] | str:
    """(factor, offset) taking a value in `src` to `dst`, or what is missing (a string)."""
    if src is None or dst is None or src == dst:
        return 1.0, 0.0  # a dimensionless side is taken as it is
    defs = []
    for name in (src, dst):
        d = next((t[name] for t in tables if name in t), None)
        if d is None:
            return (f"the unit {shorten(name, 100)} has no definition (ssd:Units, the parameter set's ssv:Units or "
                    "the FMU's)")
        defs.append(d)
    a, b = defs
    if a.exponents != b.exponents:
        return f"{shorten(src, 100)} cannot be converted to {shorten(dst, 100)} (different base units)"
    if a.factor == b.factor and a.offset == b.offset:
        return 1.0, 0.0
    # base = factor * value + offset on each side
    return a.factor / b.factor, (a.offset - b.offset) / b.factor


def number(doc: Doc, el, attr: str, default: float | None = None) -> float:
    text = el.get(attr)
    if text is None:
        if default is None:
            raise doc.fail(el, "missing required attribute; expected a number", attr)
        return default
    try:
        x = parse_real(text, XSD_SPECIAL)
    except ValueError:
        raise doc.fail(el, "expected a number (xs:double: digits, an optional sign, fraction and exponent)",
                       attr) from None
    if not math.isfinite(x):
        raise doc.fail(el, "expected a finite number", attr)
    return x


def boolean(doc: Doc, el, attr: str, default: bool = False) -> bool:
    text = el.get(attr)
    if text is None:
        return default
    if text.strip() in ("true", "1"):
        return True
    if text.strip() in ("false", "0"):
        return False
    raise doc.fail(el, "expected true or false", attr)
