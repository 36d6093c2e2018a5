"""One FMU instance as the master sees it.

Loading goes through fmpy (``FMU2Slave``); the per-step hot path calls the
FMU's own C symbols with preallocated ctypes arrays, so that a
communication step costs a few ctypes calls and no Python-side allocation.
"""

from __future__ import annotations

import ctypes
import json
import os
import shutil
import sys
import tempfile
import threading
import zipfile
from ctypes import POINTER, byref, c_double, c_int, c_size_t, c_uint, c_void_p
from dataclasses import dataclass
from pathlib import Path

from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.fmi2 import fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE
from fmpy import calloc, free

from ..atomic import alive
from ..errors import ParametersRefused, SceneError, SimulationError
from ..hashing import sha256_file
from ..paths import cache_root, scratch_dir
from .description import check_archive, read_fmu, var_unit

OK, WARNING, DISCARD, ERROR, FATAL = 0, 1, 2, 3, 4
STATUS_NAMES = ["OK", "Warning", "Discard", "Error", "Fatal", "Pending"]

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
    path = Path(path).resolve()
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
            print(f"clockwork: warning: {target}: damaged FMU cache entry, extracting {path.name} again",
                  file=sys.stderr)
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
    with zipfile.ZipFile(path) as z:
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
        manifest = json.loads((folder / _MANIFEST).read_text())
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


def free_all(instances: dict) -> None:
    """Free every instance, whatever state each is in."""
    for inst in instances.values():
        try:
            inst.free()
        except Exception:
            pass


@dataclass
class Variable:
    name: str
    vr: int
    type: str
    causality: str
    variability: str
    unit: str | None
    dependencies: list[str] | None  # direct feedthrough inputs (outputs only)


class Instance:
    """An instantiated FMU with fast access to its fmi2 functions."""

    def __init__(self, name: str, path: Path, model_description=None):
        self.name = name
        self.path = Path(path)
        described = read_fmu(self.path, need_binary=False)
        self.md = model_description or described[0]
        self.model_name = self.md.modelName
        self.variables: dict[str, Variable] = {}
        by_index = list(self.md.modelVariables)
        deps: dict[str, list[str]] = {}
        for u in self.md.outputs:
            deps[u.variable.name] = (
                None if u.dependencies is None else [d.name for d in u.dependencies]
            )
        for v in by_index:
            self.variables[v.name] = Variable(
                v.name, v.valueReference, v.type, v.causality, v.variability,
                var_unit(v),
                deps.get(v.name),
            )
        cs = self.md.coSimulation
        self.max_output_derivative_order = int(cs.maxOutputDerivativeOrder or 0)
        self.can_interpolate_inputs = bool(cs.canInterpolateInputs)
        self.can_get_set_state = bool(cs.canGetAndSetFMUstate)
        self.event_indicators = list(described[2])
        self.messages: list[tuple[int, str]] = []
        self._slave = None
        self._state = c_void_p()

    # -- loading -------------------------------------------------------

    def instantiate(self) -> None:
        unzip = extract(self.path)
        try:
            self._slave = FMU2Slave(
                guid=self.md.guid,
                unzipDirectory=str(unzip),
                modelIdentifier=self.md.coSimulation.modelIdentifier,
                instanceName=self.name,
            )
        except Exception as e:  # fmpy raises a bare Exception for a bad library
            raise SceneError(f"{self.path}: cannot load the FMU's binary for this platform: {e}") from None
        messages = self.messages

        def logger(env, instance_name, status, category, message):
            messages.append((status, message.decode("utf-8", "replace")))
            del messages[:-50]

        self._callbacks = fmi2CallbackFunctions()
        self._callbacks.logger = fmi2CallbackLoggerTYPE(logger)
        # libc's own calloc and free, cast rather than wrapped: a wrapper
        # would be a Python callback on every allocation inside the FMU.
        self._callbacks.allocateMemory = ctypes.cast(calloc, fmi2CallbackAllocateMemoryTYPE)
        self._callbacks.freeMemory = ctypes.cast(free, fmi2CallbackFreeMemoryTYPE)
        try:
            self._slave.instantiate(callbacks=self._callbacks)
        except Exception as e:
            # The binary refused its own model description (another build or
            # another model): the FMU file is broken, which is bad input.
            raise SceneError(
                f"{self.path}: fmi2Instantiate refused the model description's GUID "
                f"{self.md.guid}: {self.last_message() or e}") from None
        self.component = self._slave.component
        dll = self._slave.dll
        self._bind(dll)

    def _bind(self, dll) -> None:
        """Raw C symbols with argtypes, bypassing fmpy's per-call wrappers."""

        def fn(name, *argtypes):
            f = getattr(dll, name)
            f.argtypes = list(argtypes)
            f.restype = c_int
            return f

        comp = c_void_p
        self.c_doStep = fn("fmi2DoStep", comp, c_double, c_double, c_int)
        self.c_getReal = fn("fmi2GetReal", comp, POINTER(c_uint), c_size_t, POINTER(c_double))
        self.c_setReal = fn("fmi2SetReal", comp, POINTER(c_uint), c_size_t, POINTER(c_double))
        self.c_getInteger = fn("fmi2GetInteger", comp, POINTER(c_uint), c_size_t, POINTER(c_int))
        self.c_setInteger = fn("fmi2SetInteger", comp, POINTER(c_uint), c_size_t, POINTER(c_int))
        self.c_setBoolean = fn("fmi2SetBoolean", comp, POINTER(c_uint), c_size_t, POINTER(c_int))
        self.c_getBoolean = fn("fmi2GetBoolean", comp, POINTER(c_uint), c_size_t, POINTER(c_int))
        self.c_setInputDerivatives = fn(
            "fmi2SetRealInputDerivatives", comp, POINTER(c_uint), c_size_t, POINTER(c_int), POINTER(c_double)
        )
        self.c_getOutputDerivatives = fn(
            "fmi2GetRealOutputDerivatives", comp, POINTER(c_uint), c_size_t, POINTER(c_int), POINTER(c_double)
        )
        self.c_getState = fn("fmi2GetFMUstate", comp, POINTER(c_void_p))
        self.c_setState = fn("fmi2SetFMUstate", comp, c_void_p)
        self.c_freeState = fn("fmi2FreeFMUstate", comp, POINTER(c_void_p))
        self.c_reset = fn("fmi2Reset", comp)
        self.c_setup = fn("fmi2SetupExperiment", comp, c_int, c_double, c_double, c_int, c_double)
        self.c_enterInit = fn("fmi2EnterInitializationMode", comp)
        self.c_exitInit = fn("fmi2ExitInitializationMode", comp)
        self.c_terminate = fn("fmi2Terminate", comp)

    @property
    def freed(self) -> bool:
        """Whether free() ran (an instance never instantiated is not freed)."""
        return self._slave is None and hasattr(self, "component")

    def free(self) -> None:
        if self._slave is None:
            return
        if self._state.value:
            self.c_freeState(self.component, byref(self._state))
        try:
            self._slave.fmi2FreeInstance(self.component)
        finally:
            self._slave = None

    # -- status handling ------------------------------------------------

    def last_message(self) -> str:
        return self.messages[-1][1] if self.messages else ""

    def fail(self, what: str, status: int, time: float | None = None,
             error: type[SimulationError] = SimulationError) -> SimulationError:
        msg = self.last_message()
        text = f"{self.model_name}: {what} returned {STATUS_NAMES[status]}"
        if msg:
            text += f": {msg}"
        return error(text, time=time, instance=self.name)

    def check(self, status: int, what: str, time: float | None = None,
              error: type[SimulationError] = SimulationError) -> None:
        if status > WARNING:
            raise self.fail(what, status, time, error)

    # -- setup ----------------------------------------------------------

    def setup(self, start: float, parameters: dict[str, object]) -> None:
        """fmi2SetupExperiment, parameters, initialization mode."""
        self.check(self.c_setup(self.component, 0, 0.0, start, 0, 0.0), "fmi2SetupExperiment")
        self.set_values(parameters, "setting parameters", ParametersRefused)
        self.check(self.c_enterInit(self.component), "fmi2EnterInitializationMode")

    def set_values(self, values: dict[str, object], what: str = "fmi2Set*",
                   error: type[SimulationError] = SimulationError) -> None:
        for name, value in values.items():
            v = self.variables[name]
            vr = (c_uint * 1)(v.vr)
            if v.type == "Real":
                st = self.c_setReal(self.component, vr, 1, (c_double * 1)(float(value)))
            elif v.type == "Integer":
                st = self.c_setInteger(self.component, vr, 1, (c_int * 1)(int(value)))
            elif v.type == "Boolean":
                st = self.c_setBoolean(self.component, vr, 1, (c_int * 1)(1 if value else 0))
            else:
                raise SimulationError(f"{self.name}.{name}: type {v.type} is not supported")
            self.check(st, f"{what} ({name} = {value!r})", error=error)

    def exit_init(self) -> None:
        self.check(self.c_exitInit(self.component), "fmi2ExitInitializationMode", error=ParametersRefused)

    def reset(self) -> None:
        """fmi2Reset: back to the state right after instantiation."""
        self.check(self.c_reset(self.component), "fmi2Reset")
        del self.messages[:]  # an error after the reset must not quote one from before

    # -- convenience getters (not on the hot path) ----------------------

    def get_real(self, names: list[str]) -> list[float]:
        vrs = (c_uint * len(names))(*[self.variables[n].vr for n in names])
        out = (c_double * len(names))()
        self.check(self.c_getReal(self.component, vrs, len(names), out), "fmi2GetReal")
        return list(out)

    def get_integer(self, names: list[str]) -> list[int]:
        vrs = (c_uint * len(names))(*[self.variables[n].vr for n in names])
        out = (c_int * len(names))()
        self.check(self.c_getInteger(self.component, vrs, len(names), out), "fmi2GetInteger")
        return list(out)

    def get_boolean(self, names: list[str]) -> list[bool]:
        vrs = (c_uint * len(names))(*[self.variables[n].vr for n in names])
        out = (c_int * len(names))()
        self.check(self.c_getBoolean(self.component, vrs, len(names), out), "fmi2GetBoolean")
        return [bool(x) for x in out]

    def output_derivatives(self, names: list[str], order: int) -> list[float] | None:
        """Derivatives of outputs, or None when the FMU does not offer them."""
        if order > self.max_output_derivative_order:
            return None
        n = len(names)
        vrs = (c_uint * n)(*[self.variables[x].vr for x in names])
        orders = (c_int * n)(*([order] * n))
        out = (c_double * n)()
        keep = len(self.messages)
        if self.c_getOutputDerivatives(self.component, vrs, n, orders, out) > WARNING:
            del self.messages[keep:]  # an unsupported derivative is not an error
            return None
        return list(out)

    # -- FMU state ------------------------------------------------------

    def save_state(self, t: float | None = None) -> None:
        """Overwrite this instance's one saved state (no allocation growth); t (s) names the point in errors."""
        self.check(self.c_getState(self.component, byref(self._state)), "fmi2GetFMUstate", t)

    def restore_state(self, t: float | None = None) -> None:
        self.check(self.c_setState(self.component, self._state), "fmi2SetFMUstate", t)
