"""Content digests: of files (FMUs, results) and of the package's own code."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

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
    results computed by older code.
    """
    global _SOURCE_DIGEST
    if _SOURCE_DIGEST is None:
        root = Path(__file__).resolve().parent
        h = hashlib.sha256()
        for f in sorted(root.rglob("*.py")):
            h.update(str(f.relative_to(root)).encode())
            h.update(b"\0")
            h.update(f.read_bytes())
        _SOURCE_DIGEST = h.hexdigest()[:16]
    return _SOURCE_DIGEST
