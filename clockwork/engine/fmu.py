"""One FMU instance as the master sees it.

Loading goes through fmpy (``FMU2Slave``); the per-step hot path calls the
FMU's own C symbols with preallocated ctypes arrays, so that a
communication step costs a few ctypes calls and no Python-side allocation.
"""

from __future__ import annotations

import collections
import copy
import ctypes
import json
import os
import shutil
import signal
import tempfile
import threading
import weakref
import zipfile
from ctypes import CFUNCTYPE, POINTER, byref, c_char_p, c_double, c_int, c_size_t, c_uint, c_void_p
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.fmi2 import fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE
from fmpy import calloc, free

from .. import watchdog
from ..atomic import alive
from ..errors import ParametersRefused, SceneError, SimulationError, UsageError, say
from ..files import open_regular, read_regular
from ..hashing import sha256_file
from ..numbers import parse_json
from ..paths import cache_root, core_library, scratch_dir
from .description import (check_archive, default_tolerance, default_tolerance_problem, outputs_after_inputs,
                          read_fmu, resolved, var_unit)

OK, WARNING, DISCARD, ERROR, FATAL = 0, 1, 2, 3, 4
STATUS_NAMES = ["OK", "Warning", "Discard", "Error", "Fatal", "Pending"]
LAST_SUCCESSFUL_TIME, TERMINATED = 2, 3  # fmi2StatusKind
NO_MESSAGE = "(the FMU logged no message)"


# What the compiled core's formatting logger (cw_logger) hands on: the
# instance name, the status, the category and the formatted text.
_SINK = CFUNCTYPE(None, c_char_p, c_int, c_char_p, c_char_p)
NO_SINK = _SINK()  # NULL: an environment that is no logger's (FMI 3.0's intermediate update)
_formatter: list = []  # [(cw_logger as an fmi2 logger, the core library), or None]
_formatter_lock = threading.Lock()

# Messages an FMU logged through an environment and an instance name that
# are no live instance's (cw_guard.c routes them here): kept, the last 50,
# for last_message() of an instance that failed without a message of its own.
unattributed: collections.deque = collections.deque(maxlen=50)


def _unattributed(instance, status, category, text):
    name = instance.decode("utf-8", "replace") if instance else ""
    unattributed.append((name, status, text.decode("utf-8", "replace") if text else ""))


_fallback_sink = _SINK(_unattributed)


def formatting_logger():
    """The core library's cw_logger, which formats an FMU's printf-style
    message with its arguments (ctypes cannot reach C varargs) and hands it
    to the sink registered for the componentEnvironment (cw_guard.c: it
    trusts nothing the FMU passes), with the library; or None when the
    library is not built: then messages are the raw format."""
    with _formatter_lock:
        if not _formatter:
            try:
                lib = ctypes.CDLL(str(core_library()))
                lib.cw_env_register.argtypes = [c_void_p, c_char_p, _SINK]
                lib.cw_env_register.restype = c_int
                lib.cw_env_unregister.argtypes = [c_void_p]
                lib.cw_env_unregister.restype = None
                lib.cw_env_fallback.argtypes = [_SINK]
                lib.cw_env_fallback.restype = None
                lib.cw_env_fallback(_fallback_sink)
                lib.cw_env_known.argtypes = [c_void_p]
                lib.cw_env_known.restype = c_int
                lib.cw_read_string.argtypes = [c_void_p, c_char_p, c_size_t]
                lib.cw_read_string.restype = ctypes.c_long
                lib.cw_crash_install.argtypes = [c_int]
                lib.cw_crash_install.restype = c_int
                lib.cw_crash_binary.argtypes = [c_void_p]
                lib.cw_crash_binary.restype = c_int
                lib.cw_crash_info.argtypes = [c_void_p, POINTER(c_int), c_char_p, c_size_t]
                lib.cw_crash_info.restype = c_int
                lib.cw_crash_line.argtypes = []
                lib.cw_crash_line.restype = c_char_p
                # A forked child (a pool worker) has no watchdog: its crash
                # handler must not write to the parent's pipe's number.
                os.register_at_fork(after_in_child=lambda: lib.cw_crash_install(-1))
                _formatter.append((ctypes.cast(lib.cw_logger, fmi2CallbackLoggerTYPE), lib))
            except (OSError, AttributeError):
                _formatter.append(None)
        return _formatter[0]


def quiet_crashes() -> None:
    """In a sweep worker: a crash the core cannot return from ends the
    process without a line of its own (the parent reports the worker's end)."""
    global _quiet
    core = formatting_logger()
    if core is not None:
        core[1].cw_crash_install(-2)
    _quiet = True


_quiet = False


def guard_library(dll, names: tuple[str, ...], instance: str) -> int | None:
    """Put the FMU library `dll` under the core's crash handler (cw_guard.c):
    a fatal signal inside it makes the FMI call it was in return fmi2Fatal
    (or NULL), and the run fail. Returns the address of one of its
    functions (`names`: the first it has), which names the library to
    cw_crash_info; None without the core. Nothing is added to any call."""
    core = formatting_logger()
    if core is None:
        return None
    for name in names:
        try:
            address = ctypes.cast(getattr(dll, name), c_void_p).value
        except AttributeError:
            continue
        lib = core[1]
        if not _quiet:
            lib.cw_crash_install(watchdog.crash_fd())
        watchdog.describe_crash(_describe_crash)
        if lib.cw_crash_binary(c_void_p(address)) != 0:
            return None
        with _formatter_lock:
            instances = _guarded_names.setdefault(address, [])
            if instance not in instances:
                instances.append(instance)
        return address
    return None


_guarded_names: dict[int, list[str]] = {}  # guard_library's address -> the instances of that library


def _describe_crash() -> str:
    """The line for a crash the core could not return from (watchdog)."""
    for address, names in list(_guarded_names.items()):
        crash = crash_of(address)
        if crash is not None:
            return f"{', '.join(names[:5])}: the FMU crashed in {crash}"
    core = formatting_logger()
    return core[1].cw_crash_line().decode("utf-8", "replace") if core else ""


_SIGNAL_WHAT = {"SIGSEGV": "a segmentation fault", "SIGBUS": "a bus error", "SIGFPE": "an arithmetic fault",
                "SIGILL": "an illegal instruction", "SIGABRT": "an abort"}


def crashes(address: int | None) -> int:
    """How many times the library that holds `address` (guard_library) crashed."""
    core = formatting_logger()
    if core is None or not address:
        return 0
    return core[1].cw_crash_info(c_void_p(address), None, None, 0)


def crash_of(address: int | None, seen: int = 0) -> str | None:
    """What crashed the library that holds `address` (guard_library) last,
    as "fmi2DoStep (SIGSEGV, a segmentation fault)", or None when it did not
    crash more than `seen` times."""
    core = formatting_logger()
    if core is None or not address:
        return None
    call = ctypes.create_string_buffer(96)
    signo = c_int(0)
    if core[1].cw_crash_info(c_void_p(address), byref(signo), call, len(call)) <= seen:
        return None
    sig = signo.value
    try:
        name = signal.Signals(sig).name
    except ValueError:
        name = f"signal {sig}"
    call_name = call.value.decode("utf-8", "replace") or "an FMI call"
    return f"{call_name} ({name}, {_SIGNAL_WHAT.get(name, 'a crash')})"


def read_string(address) -> str:
    """A string an FMU passed to a callback (an address, or None), read
    without trusting it: through the core's cw_read_string (an unreadable
    address is no fault), else as ctypes reads it."""
    if not address:
        return ""
    core = formatting_logger()
    if core is None:
        return ctypes.string_at(address).decode("utf-8", "replace")
    buf = ctypes.create_string_buffer(65536)
    n = core[1].cw_read_string(c_void_p(address), buf, len(buf))
    if n < 0:
        return "(the FMU passed an unreadable message)"
    return buf.raw[:n].decode("utf-8", "replace")


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
    dependencies: list[str] | None  # the inputs an output depends on directly (outputs only; else None)
    shape: tuple[int, ...] = ()  # an FMI 3.0 array's shape; () for a scalar or an element
    array: str | None = None  # an array element's array (its vr is the element's code, fmu3.Instance3)
    index: int = 0  # an array element's place in its array's values (row-major)


def direct_feedthrough(md) -> dict[str, list[str]]:
    """{output: the inputs it depends on directly}, from the ModelStructure.

    Only a dependency on a variable of causality "input" is direct
    feedthrough: outputs that depend on states, parameters or locals only
    (a Dymola motor's current, a pendulum's angle) are known at the
    communication point without their inputs. A missing `dependencies`
    attribute means "depends on all knowns" (FMI 2.0, 3.3.2), hence on every
    input. Every dependenciesKind is a dependency, so the kinds do not matter.
    """
    inputs = [v.name for v in md.modelVariables if v.causality == "input"]
    return {u.variable.name: list(inputs) if u.dependencies is None
            else [d.name for d in u.dependencies if d.causality == "input"] for u in md.outputs}


# fmpy's slave object for the first instance of each binary; later
# instances get a copy. fmpy's constructor loads the library (the dynamic
# loader gives every instance of one path the same one anyway) and
# declares each FMI function's argument types from its Python signature,
# milliseconds per instance, which a system of hundreds of FMUs would pay
# hundreds of times.
_slaves: dict[tuple, object] = {}
_slaves_lock = threading.Lock()


def new_slave(kind: type, unzip: Path, md, name: str, model_identifier: str):
    """A fmpy object (`kind`: FMU2Slave, FMU3Slave, FMU2Model) named `name`,
    not yet instantiated, on the FMU's library (`model_identifier`: of the
    interface it runs through) as loaded once."""
    key = (kind, str(unzip), model_identifier)
    with _slaves_lock:
        first = _slaves.get(key)
        if first is None:
            first = _slaves[key] = kind(guid=md.guid, unzipDirectory=str(unzip),
                                        modelIdentifier=model_identifier, instanceName=name)
    slave = copy.copy(first)
    slave.guid, slave.instanceName, slave.component, slave.callbacks = md.guid, name, None, None
    return slave


def declared(dll, name: str, argtypes: tuple):
    """The C function `name` of a loaded library, with these argument types
    and an int status, declared once: the instances of one FMU share its
    library's function objects."""
    f = getattr(dll, name)
    if f.argtypes != argtypes or f.restype is not c_int:
        f.argtypes, f.restype = argtypes, c_int
    return f


# The variables as the master sees them, one table per model description
# (per FMU file), shared read-only by all its instances.
_INSTANCE_VARIABLES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def instance_variables(md) -> MappingProxyType:
    """{name: Variable} of a model description, built on first use."""
    table = _INSTANCE_VARIABLES.get(md)
    if table is None:
        deps = direct_feedthrough(md)
        table = _INSTANCE_VARIABLES[md] = MappingProxyType({
            v.name: Variable(v.name, v.valueReference, v.type, v.causality, v.variability, var_unit(v),
                             deps.get(v.name))
            for v in md.modelVariables})
    return table


class Instance:
    """An instantiated FMU with fast access to its fmi2 functions."""

    fmi_version = 2  # fmu3.Instance3 says 3, fmu1.Instance1 1
    do_step_name = "fmi2DoStep"  # in messages
    _fmpy_class = FMU2Slave  # model_exchange.MEInstance: FMU2Model
    # Instances freed in this process: a master looks for a freed instance
    # of its own before a run only when this changed (systems have thousands).
    frees = 0
    # Its binary under the core's crash handler (guard_library's address, or
    # None), and the crashes of that binary before this instance was made.
    _guarded: int | None = None
    _crashes_seen = 0

    def _guard(self, dll, names: tuple[str, ...]) -> None:
        """Put this instance's binary under the crash handler (`names`: the
        functions that may name the library, the first it has)."""
        self._guarded = guard_library(dll, names, self.name)
        self._crashes_seen = crashes(self._guarded)  # an earlier instance's crash is not this one's

    def _interface(self):
        """The modelDescription element of the interface it runs through."""
        return self.md.coSimulation
    arrays: dict[str, tuple[int, int]] = {}  # FMI 3.0 array variables: name -> (vr, values) (fmu3.Instance3)
    elements: dict[str, list[str]] = {}  # FMI 3.0 array variables: name -> its element names, row-major
    # What messages call the FMU where its path is a copy (an SSP archive's
    # member, "x.ssp/resources/m.fmu"); None: its path.
    label: str | None = None

    @property
    def shown(self) -> str:
        return self.label or str(self.path)

    def __reduce_ex__(self, protocol):
        raise UsageError(f"the FMU instance {self.name} cannot be pickled or copied: it is a loaded library "
                         "and its C state")

    def __init__(self, name: str, path: Path, model_description=None):
        self.name = name
        self.path = Path(path)
        described = read_fmu(self.path, need_binary=False)
        self.md = model_description or described[0]
        self.model_name = self.md.modelName
        self.variables = instance_variables(self.md)
        self._read_capabilities()
        self.outputs_after_inputs = self._outputs_after_inputs()
        self.default_tolerance = default_tolerance(self.md)
        self.event_indicators = list(described[2])
        self.messages: list[tuple[int, str]] = []
        self._slave = None
        self._state = c_void_p()

    def _outputs_after_inputs(self) -> bool:
        """Whether the master may read outputs after setting inputs with no
        step between (engine/wiring.py): FMI 2.0 (4.2.4) and FMI 3.0's Step
        Mode forbid it unless the description says so in clockwork's
        annotation (description.declares_outputs_after_inputs)."""
        return outputs_after_inputs(self.path)

    def _read_capabilities(self) -> None:
        """What the FMU's <CoSimulation> element declares (a Model Exchange wrapper says its own)."""
        cs = self.md.coSimulation
        self.max_output_derivative_order = int(cs.maxOutputDerivativeOrder or 0)
        self.can_interpolate_inputs = bool(cs.canInterpolateInputs)
        self.can_get_set_state = bool(cs.canGetAndSetFMUstate)

    # -- loading -------------------------------------------------------

    def instantiate(self) -> None:
        unzip = extract(self.path)
        try:
            self._slave = new_slave(self._fmpy_class, unzip, self.md, self.name, self._interface().modelIdentifier)
        except Exception as e:  # fmpy raises a bare Exception for a bad library
            raise SceneError(f"{self.shown}: cannot load the FMU's binary for this platform: {e}") from None
        messages = self.messages

        def keep(status, message):
            messages.append((status, message.decode("utf-8", "replace") if message else ""))
            del messages[:-50]

        self._guard(self._slave.dll, ("fmi2Instantiate",))
        self._callbacks = fmi2CallbackFunctions()
        core = formatting_logger()
        if core is not None:
            # cw_logger formats and hands the text to this instance's sink,
            # which it finds in the core's registry of live environments by
            # the componentEnvironment (or, when the FMU passes another, by
            # the instance name): an environment is only ever looked up.
            self._sink = _SINK(lambda instance, status, category, text: keep(status, text))
            env = ctypes.cast(self._sink, c_void_p).value
            self._callbacks.logger = core[0]
            self._callbacks.componentEnvironment = env
            core[1].cw_env_register(env, self.name.encode("utf-8", "replace"), self._sink)
            # Forgotten when freed (free() calls it), or when this object goes.
            self._forget_env = weakref.finalize(self, core[1].cw_env_unregister, env)
        else:
            self._callbacks.logger = fmi2CallbackLoggerTYPE(
                lambda env, instance, status, category, message: keep(status, message))
        # libc's own calloc and free, cast rather than wrapped: a wrapper
        # would be a Python callback on every allocation inside the FMU.
        self._callbacks.allocateMemory = ctypes.cast(calloc, fmi2CallbackAllocateMemoryTYPE)
        self._callbacks.freeMemory = ctypes.cast(free, fmi2CallbackFreeMemoryTYPE)
        try:
            self._slave.instantiate(callbacks=self._callbacks)
        except Exception as e:
            self._forget()
            self.check_crash("fmi2Instantiate")
            # The binary refused its own model description (another build or
            # another model): the FMU file is broken, which is bad input.
            raise SceneError(
                f"{self.shown}: fmi2Instantiate refused the model description's GUID "
                f"{self.md.guid}: {self.last_message() or e}") from None
        self.component = self._slave.component
        dll = self._slave.dll
        self._bind(dll)

    def _bind(self, dll) -> None:
        """Raw C symbols with argtypes, bypassing fmpy's per-call wrappers."""

        def fn(name, *argtypes):
            return declared(dll, name, argtypes)

        comp = c_void_p
        self.c_doStep = fn("fmi2DoStep", comp, c_double, c_double, c_int)
        self.c_getReal = fn("fmi2GetReal", comp, POINTER(c_uint), c_size_t, POINTER(c_double))
        self.c_setReal = fn("fmi2SetReal", comp, POINTER(c_uint), c_size_t, POINTER(c_double))
        self.c_getInteger = fn("fmi2GetInteger", comp, POINTER(c_uint), c_size_t, POINTER(c_int))
        self.c_setInteger = fn("fmi2SetInteger", comp, POINTER(c_uint), c_size_t, POINTER(c_int))
        self.c_setBoolean = fn("fmi2SetBoolean", comp, POINTER(c_uint), c_size_t, POINTER(c_int))
        self.c_getBoolean = fn("fmi2GetBoolean", comp, POINTER(c_uint), c_size_t, POINTER(c_int))
        self.c_getString = fn("fmi2GetString", comp, POINTER(c_uint), c_size_t, POINTER(c_char_p))
        self.c_setString = fn("fmi2SetString", comp, POINTER(c_uint), c_size_t, POINTER(c_char_p))
        self.c_getBooleanStatus = fn("fmi2GetBooleanStatus", comp, c_int, POINTER(c_int))
        self.c_getRealStatus = fn("fmi2GetRealStatus", comp, c_int, POINTER(c_double))
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

    def crash(self) -> str | None:
        """What crashed this instance's FMU binary in this process (its call
        and the signal), or None: such an FMU is not called again."""
        return crash_of(self._guarded, self._crashes_seen)

    def check_crash(self, what: str) -> None:
        """Raise the failed run when the FMU crashed (a failed instantiate)."""
        if self.crash() is not None:
            raise self.fail(what, FATAL)

    def free(self) -> None:
        if self._slave is None:
            return
        if self.crash() is not None:  # its code and state are not to be trusted again: left as it is
            self._slave = None
            self._forget()
            Instance.frees += 1
            return
        if self._state.value:
            self.c_freeState(self.component, byref(self._state))
        try:
            self._free_instance()
        finally:
            self._slave = None
            self._forget()
            Instance.frees += 1

    def _forget(self) -> None:
        """Take this instance's logger environment out of the core's registry."""
        forget = getattr(self, "_forget_env", None)
        if forget is not None:
            forget()

    def _free_instance(self) -> None:
        self._slave.fmi2FreeInstance(self.component)

    # -- status handling ------------------------------------------------

    def last_message(self) -> str:
        """The FMU's last message that reports a failure (status Discard or
        worse): an earlier warning or remark does not explain a failure."""
        for status, text in reversed(self.messages):
            if status >= DISCARD and text:
                return text
        for _, status, text in reversed(unattributed):  # logged through a bad environment and name
            if status >= DISCARD and text:
                return f"{text} (logged through no live instance's environment or name)"
        return ""

    def fail(self, what: str, status: int, time: float | None = None,
             error: type[SimulationError] = SimulationError) -> SimulationError:
        crash = self.crash()
        if crash is not None:
            return error(f"{self.model_name}: {what} crashed the FMU in {crash}; the call was abandoned",
                         time=time, instance=self.name)
        name = STATUS_NAMES[status] if 0 <= status < len(STATUS_NAMES) else f"status {status}"
        text = f"{self.model_name}: {what} returned {name}: {self.last_message() or NO_MESSAGE}"
        return error(text, time=time, instance=self.name)

    def terminated(self) -> bool:
        """fmi2GetBooleanStatus(fmi2Terminated): the FMU wants the simulation
        to end (asked after a discarded step; an FMU that cannot say, says no)."""
        value = c_int(0)
        keep = len(self.messages)
        if self.c_getBooleanStatus(self.component, TERMINATED, byref(value)) > WARNING:
            del self.messages[keep:]  # not providing the status is no error
            return False
        return bool(value.value)

    def last_successful_time(self) -> float | None:
        """fmi2GetRealStatus(fmi2LastSuccessfulTime), s, or None."""
        value = c_double(0.0)
        keep = len(self.messages)
        if self.c_getRealStatus(self.component, LAST_SUCCESSFUL_TIME, byref(value)) > WARNING:
            del self.messages[keep:]
            return None
        return value.value

    def check(self, status: int, what: str, time: float | None = None,
              error: type[SimulationError] = SimulationError) -> None:
        if status > WARNING:
            raise self.fail(what, status, time, error)

    # -- setup ----------------------------------------------------------

    def setup(self, start: float, parameters: dict[str, object], tolerance: float | None = None) -> None:
        """fmi2SetupExperiment (with the relative tolerance when one is
        given: the scene's, else the FMU's DefaultExperiment's), parameters,
        initialization mode."""
        if tolerance is None:
            tolerance = self.default_tolerance
            problem = default_tolerance_problem(self.md)
            if problem:  # the scene layer refuses it first
                raise SceneError(f"{self.shown}: modelDescription.xml: DefaultExperiment tolerance = {tolerance:g}: "
                                 f"{problem}; or give master.tolerance")
        defined = tolerance is not None
        self.check(self.c_setup(self.component, int(defined), float(tolerance) if defined else 0.0, start, 0, 0.0),
                   "fmi2SetupExperiment")
        self.set_values(parameters, "setting parameters", ParametersRefused)
        self.check(self.c_enterInit(self.component), "fmi2EnterInitializationMode")

    def set_values(self, values: dict[str, object], what: str = "fmi2Set*",
                   error: type[SimulationError] = SimulationError) -> None:
        for name, value in values.items():
            v = self.variables[name]
            vr = (c_uint * 1)(v.vr)
            if v.type == "Real":
                st = self.c_setReal(self.component, vr, 1, (c_double * 1)(float(value)))
            elif v.type in ("Integer", "Enumeration"):
                st = self.c_setInteger(self.component, vr, 1, (c_int * 1)(int(value)))
            elif v.type == "Boolean":
                st = self.c_setBoolean(self.component, vr, 1, (c_int * 1)(1 if value else 0))
            elif v.type == "String":
                st = self.c_setString(self.component, vr, 1, (c_char_p * 1)(str(value).encode("utf-8")))
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

    def get_string(self, names: list[str]) -> list[str]:
        vrs = (c_uint * len(names))(*[self.variables[n].vr for n in names])
        out = (c_char_p * len(names))()
        self.check(self.c_getString(self.component, vrs, len(names), out), "fmi2GetString")
        return [(x or b"").decode("utf-8", "replace") for x in out]

    def get_values(self, names: list[str]) -> list:
        """Values of any type, each through the fmi2Get* of its type
        (Enumeration through fmi2GetInteger); not on the hot path."""
        getters = {"Real": self.get_real, "Integer": self.get_integer, "Enumeration": self.get_integer,
                   "Boolean": self.get_boolean, "String": self.get_string}
        return [getters[self.variables[n].type]([n])[0] for n in names]

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
