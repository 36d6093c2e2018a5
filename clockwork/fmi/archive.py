"""An FMU archive unzipped once per content: the cache of unzipped folders
(``<cache>/fmus/<sha256>/``), or a scratch folder with the cache off.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import threading
import zipfile
from pathlib import Path


from ..atomic import alive
from ..errors import say
from ..files import open_regular, read_regular
from ..hashing import sha256_file
from ..numbers import parse_json
from ..paths import cache_root, scratch_dir
from .description import check_archive, resolved


_extract_lock = threading.Lock()
_extracted: dict[tuple, Path] = {}  # (path, mtime, size) -> unzipped folder
_MANIFEST = ".clockwork-manifest"


def extract(path: Path) -> Path:
    """The FMU's unzipped folder, extracted once per content.

    With the cache on, the folder is ``<cache>/fmus/<sha256>/``, shared by
    processes and runs: a second run does not pay for the unzip. It is made
    under a temporary name and renamed into place, so that a reader never
    sees half an FMU, and it is checked against its manifest (names and
    sizes) before reuse. With the cache off (or unwritable), FMUs go to the
    process's scratch folder (clockwork.paths.scratch_dir), removed at exit.
    """
    path = resolved(path)
    st = path.stat()
    key = (str(path), st.st_mtime_ns, st.st_size)
    with _extract_lock:
        hit = _extracted.get(key)
        if hit is None:
            digest = sha256_file(path)
            hit = _extract_cached(path, digest)
            if hit is None:
                hit = _extract_into(path, scratch_dir() / "fmus" / digest)
            _extracted[key] = hit
        return hit


def _extract_cached(path: Path, digest: str) -> Path | None:
    root = cache_root()
    if root is None:
        return None
    store = root / "fmus"
    target = store / digest
    try:
        store.mkdir(parents=True, exist_ok=True)
        if target.is_dir():
            if _intact(target):
                return target
            say("warning", f"{target}: damaged FMU cache entry, extracting {path.name} again")
            shutil.rmtree(target, ignore_errors=True)
        _remove_stale_parts(store, ".", ".")
        tmp = Path(tempfile.mkdtemp(prefix=f".{os.getpid()}.{digest[:16]}.", suffix=".part", dir=store))
        try:
            _unzip(path, tmp)
            try:
                os.rename(tmp, target)
            except OSError:
                if not (target.is_dir() and _intact(target)):  # not a concurrent extraction either
                    raise
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        return target
    except OSError:
        return None  # a read-only or full cache never fails a run


def _extract_into(path: Path, target: Path) -> Path:
    if not (target.is_dir() and _intact(target)):
        shutil.rmtree(target, ignore_errors=True)
        target.mkdir(parents=True)
        _unzip(path, target)
    return target


def _unzip(path: Path, target: Path) -> None:
    with open_regular(path, "an FMU (a zip archive)") as f, zipfile.ZipFile(f) as z:
        check_archive(path, z.infolist())  # also when read_fmu's check was done on another file
        try:
            z.extractall(target)
        except OSError as e:
            if e.filename is not None:
                raise
            raise OSError(e.errno, f"{e.strerror} (unzipping {path.name})", str(target)) from None
    # What extractall wrote (it drops "../" and absolute parts of names), not the archive's names,
    # so that the check before reuse finds every file where it is.
    manifest = {str(p.relative_to(target)): p.stat().st_size for p in target.rglob("*") if p.is_file()}
    (target / _MANIFEST).write_text(json.dumps(manifest))


def _intact(folder: Path) -> bool:
    """Every file of the manifest is there with its size."""
    try:
        manifest = parse_json(read_regular(folder / _MANIFEST))
        return isinstance(manifest, dict) and all(
            (folder / name).stat().st_size == size for name, size in manifest.items())
    except (OSError, ValueError, TypeError):
        return False


def _remove_stale_parts(folder: Path, prefix: str, sep: str) -> None:
    """Remove folders that a killed process left behind: `<prefix><pid><sep>...`."""
    for entry in folder.glob(f"{prefix}*"):
        pid = entry.name[len(prefix):].split(sep, 1)[0]
        if not pid.isdigit() or int(pid) == os.getpid() or alive(int(pid)):
            continue
        shutil.rmtree(entry, ignore_errors=True)
