"""Content digests: of files (FMUs, results) and of the package's own code."""

from __future__ import annotations

import hashlib
import os

_SOURCE_DIGEST: str | None = None


def sha256_file(path: str | os.PathLike) -> str:
    """Hex sha256 of a file's bytes, read in 1 MiB blocks."""
    from .files import open_regular

    h = hashlib.sha256()
    with open_regular(path) as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def source_digest() -> str:
    """sha256 (16 hex) of every clockwork/**/*.py file, names and contents.

    Cached results carry it: a changed master or analysis must never reuse
    results computed by older code. Made once per process (every run
    pays it at start-up: os.walk and plain reads, not pathlib).
    """
    global _SOURCE_DIGEST
    if _SOURCE_DIGEST is None:
        _SOURCE_DIGEST = tree_digest(os.path.dirname(os.path.realpath(__file__)))
    return _SOURCE_DIGEST


def tree_digest(root: str | os.PathLike) -> str:
    """sha256 (16 hex) of the *.py files under `root`: each one's path
    relative to `root` ("/"-separated), a NUL and its bytes, in the order of
    the paths' parts (sorted pathlib paths' order)."""
    files = []
    for folder, dirs, names in os.walk(root):  # symlinked folders not entered, as Path.rglob
        rel = os.path.relpath(folder, root)
        parts = () if rel == os.curdir else tuple(rel.split(os.sep))
        files.extend((*parts, n) for n in names if n.endswith(".py"))
    h = hashlib.sha256()
    for parts in sorted(files):
        h.update("/".join(parts).encode())
        h.update(b"\0")
        with open(os.path.join(root, *parts), "rb") as f:
            h.update(f.read())
    return h.hexdigest()[:16]
