"""Scene files checked against every analysis and plot kind there is.

``load_scene`` is clockwork.scene.load_scene with the kinds that the
analyses and the plots register (importing them registers them all).
"""

from __future__ import annotations

import difflib
import os
from pathlib import Path

from ..analyses import registry as analyses
from ..errors import SceneError
from ..paths import scenarios_dir
from ..results.plots import registry as plots
from ..scene import Kinds
from ..scene import load_scene as _load_scene


def kinds() -> Kinds:
    return Kinds(analyses.ANALYSIS_KEYS, analyses._ANALYSIS_CONVERT, plots.PLOT_KEYS, plots._PLOT_CONVERT)


def find_scene(spec: str | os.PathLike) -> Path:
    """A scene file: a path, or the name of a bundled scene ("ziemkiewicz_fig4a")."""
    path = Path(spec)
    if path.exists() or path.suffix or len(path.parts) != 1 or not str(spec).strip():
        return path
    bundled = scenarios_dir() / f"{spec}.toml"
    if bundled.is_file():
        return bundled
    known = sorted(f.stem for f in scenarios_dir().glob("*.toml"))
    close = difflib.get_close_matches(str(spec), known, n=1)
    hint = f" (did you mean {close[0]}?)" if close else ""
    raise SceneError(f"no such scene file, and no bundled scene of that name{hint}; "
                     "`clockwork list` shows the bundled scenes", path)


def load_scene(path: str | os.PathLike, overrides=()):
    """Load, override and validate a scene file (or a bundled scene by name); raises SceneError."""
    return _load_scene(find_scene(path), overrides, kinds())
