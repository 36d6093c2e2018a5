"""Where clockwork keeps things on disk: the cache, the FMUs it looks up by
name and the scenes that come with it.

In a source checkout the FMUs are the ones CMake builds into ``fmus/`` and
the scenes are ``scenarios/``; an installed wheel carries both as package
data (``clockwork/data/fmus``, ``clockwork/data/scenarios``), found with
importlib.resources; their FMI 3.0 build is in ``fmi3/`` inside either
(``fmus/fmi3/<Name>.fmu``). ``$CLOCKWORK_FMU_DIR`` overrides where FMUs are
looked up.

The cache root is ``$CLOCKWORK_CACHE`` when set (``off``, ``0``, ``no``,
``false`` or empty disable it), else ``$XDG_CACHE_HOME/clockwork``, else
``~/.cache/clockwork``. It holds extracted FMUs (``fmus/<sha256>/``) and
finished sweep points (``<code digest>/<key>.json``).
"""

from __future__ import annotations

import atexit
import importlib.resources
import os
import shutil
import sys
import tempfile
from pathlib import Path

from .atomic import alive

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


def in_checkout() -> bool:
    """Whether this package runs from a source checkout (not an installed wheel)."""
    return (REPO / "src_c" / "models").is_dir() and (REPO / "pyproject.toml").is_file()


def _package_data(name: str) -> Path:
    # A wheel is installed unzipped, so the resource is a real folder.
    return Path(str(importlib.resources.files(__package__) / "data" / name))


def scenarios_dir() -> Path:
    """The scenes that come with clockwork (one per figure of the papers)."""
    return REPO / "scenarios" if in_checkout() else _package_data("scenarios")


def fmu_dir(fmi_version: int = 2) -> Path:
    """Where model names are looked up: $CLOCKWORK_FMU_DIR, else the
    checkout's fmus/, else the FMUs installed with the package. The FMI 3.0
    build of the same FMUs is the fmi3/ folder inside it (fmi_version=3)."""
    if fmi_version not in (2, 3):
        raise ValueError(f"fmi_version must be 2 or 3, not {fmi_version!r}")
    env = os.environ.get("CLOCKWORK_FMU_DIR")
    if env:
        base = Path(env)
    else:
        base = REPO / "fmus" if in_checkout() else _package_data("fmus")
    return base / "fmi3" if fmi_version == 3 else base


def core_library() -> Path:
    """The master's compiled stepping core: $CLOCKWORK_CORE_LIB (the
    sanitizer build's copy, for instance), else the checkout's lib/ (built
    by CMake with the FMUs), else the copy installed with the package."""
    env = os.environ.get("CLOCKWORK_CORE_LIB")
    if env:
        return Path(env)
    name = "libcw_master.so"
    return REPO / "lib" / name if in_checkout() else _package_data("lib") / name


_scratch: Path | None = None
_SCRATCH_PREFIX = "clockwork-"


def scratch_dir() -> Path:
    """This process's folder in the temporary directory, removed at exit.

    Folders that killed processes left behind (their pid is in the name and
    no longer runs) are removed when the next one is made.
    """
    global _scratch
    if _scratch is None:
        if _scratch_parent is not None:  # a worker: inside its parent's, which goes with the parent
            _scratch = Path(tempfile.mkdtemp(prefix=f"worker-{os.getpid()}-", dir=_scratch_parent))
            return _scratch
        base = Path(tempfile.gettempdir())
        for old in base.glob(f"{_SCRATCH_PREFIX}*"):
            pid = old.name[len(_SCRATCH_PREFIX):].split("-", 1)[0]
            if pid.isdigit() and int(pid) != os.getpid() and not alive(int(pid)):
                shutil.rmtree(old, ignore_errors=True)
        _scratch = Path(tempfile.mkdtemp(prefix=f"{_SCRATCH_PREFIX}{os.getpid()}-"))
        atexit.register(shutil.rmtree, _scratch, True)
    return _scratch


_scratch_parent: Path | None = None


def scratch_inside(parent: Path) -> None:
    """Call first thing in a worker process (which leaves without running
    atexit handlers, or is killed): its scratch folder is made inside
    `parent`, its parent process's, removed with it."""
    global _scratch, _scratch_parent
    _scratch, _scratch_parent = None, Path(parent)


def _usable(d: Path) -> bool:
    """Whether folder d exists (made if need be) and may be written to."""
    try:
        d.mkdir(parents=True, exist_ok=True)
    except OSError:
        return False
    return d.is_dir() and os.access(d, os.W_OK | os.X_OK)


def _matplotlib_defaults() -> list[Path]:
    """The config and cache folders matplotlib uses without $MPLCONFIGDIR
    (matplotlib._get_config_or_cache_dir)."""
    if sys.platform.startswith(("linux", "freebsd")):
        home = Path.home()
        return [Path(os.environ.get("XDG_CONFIG_HOME") or home / ".config", "matplotlib"),
                Path(os.environ.get("XDG_CACHE_HOME") or home / ".cache", "matplotlib")]
    return [Path.home() / ".matplotlib"]


def matplotlib_folder() -> None:
    """Give matplotlib a usable config folder before it is imported.

    Without $MPLCONFIGDIR and writable folders of its own (~/.config/
    matplotlib, ~/.cache/matplotlib), matplotlib makes a temporary folder
    that only its atexit handler removes (a plot process never runs those)
    and says so on stderr. The folder here is $MPLCONFIGDIR when writable,
    else matplotlib's own when writable (its font list, cached there, is then
    not made again at every run: a third of a second), else
    <cache>/matplotlib, else a folder in this process's scratch folder,
    removed at exit. Call it in the process that forks the plot process,
    before the fork (a plot process forked before matplotlib's and the
    logging module's import: this module imports neither)."""
    given = os.environ.get("MPLCONFIGDIR")
    if not given:
        try:
            defaults = _matplotlib_defaults()
        except RuntimeError:  # no home folder
            defaults = []
        if defaults and all(_usable(d) for d in defaults):
            return
    root = cache_root()
    for d in ([Path(given)] if given else []) + ([root / "matplotlib"] if root is not None else []):
        if _usable(d):
            os.environ["MPLCONFIGDIR"] = str(d)
            return
    d = scratch_dir() / "matplotlib"
    d.mkdir(exist_ok=True)
    os.environ["MPLCONFIGDIR"] = str(d)
