"""Where clockwork keeps things on disk: the cache, and the FMUs it looks up by name.

The cache root is ``$CLOCKWORK_CACHE`` when set (``off``, ``0``, ``no``,
``false`` or empty disable it), else ``$XDG_CACHE_HOME/clockwork``, else
``~/.cache/clockwork``. It holds extracted FMUs (``fmus/<sha256>/``) and
finished sweep points (``<code digest>/<key>.json``).
"""

from __future__ import annotations

import os
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
_OFF = ("", "0", "off", "no", "false")


def cache_root() -> Path | None:
    """The cache directory, or None when the cache is switched off."""
    env = os.environ.get("CLOCKWORK_CACHE")
    if env is not None:
        if env.strip().lower() in _OFF:
            return None
        return Path(env).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    if xdg and Path(xdg).is_absolute():  # the XDG spec ignores relative values
        return Path(xdg) / "clockwork"
    return Path.home() / ".cache" / "clockwork"


def fmu_dir() -> Path:
    """Where model names are looked up: $CLOCKWORK_FMU_DIR, else the repository's fmus/."""
    env = os.environ.get("CLOCKWORK_FMU_DIR")
    return Path(env) if env else REPO / "fmus"
