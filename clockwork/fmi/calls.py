"""What every face's calls share: the status codes, the core's formatting
logger, the crash guard around an FMU's binary, strings an FMU hands over,
and fmpy's loader, once per binary.
"""

from __future__ import annotations

import collections
import copy
import ctypes
import os
import signal
import threading
from ctypes import CFUNCTYPE, POINTER, byref, c_char_p, c_int, c_size_t, c_void_p
from pathlib import Path

from fmpy import calloc, free
from fmpy.fmi1 import fmi1CallbackAllocateMemoryTYPE, fmi1CallbackFreeMemoryTYPE, fmi1CallbackLoggerTYPE
from fmpy.fmi2 import fmi2CallbackLoggerTYPE

from .. import watchdog
from ..paths import core_library


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
# are no live instance's (cw_log.c routes them here): kept, the last 50,
# for last_message() of an instance that failed without a message of its own.
unattributed: collections.deque = collections.deque(maxlen=50)


def _unattributed(instance, status, category, text):
    name = instance.decode("utf-8", "replace") if instance else ""
    unattributed.append((name, status, text.decode("utf-8", "replace") if text else ""))


_fallback_sink = _SINK(_unattributed)


def formatting_logger():
    """The core library's cw_logger, which formats an FMU's printf-style
    message with its arguments (ctypes cannot reach C varargs) and hands it
    to the sink registered for the componentEnvironment (cw_log.c: it
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



def free_all(instances: dict) -> None:
    """Free every instance, whatever state each is in."""
    for inst in instances.values():
        try:
            inst.free()
        except Exception:
            pass



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


# FMI 1.0's logger: (component, instance name, status, category, message),
# the strings as addresses read by read_string.
FMI1_LOGGER = CFUNCTYPE(None, c_void_p, c_void_p, c_int, c_void_p, c_void_p)


def fmi1_callbacks(struct_type, messages: list):
    """An FMI 1.0 callbacks struct of `struct_type` (Co-Simulation's has
    stepFinished, Model Exchange's not) whose logger keeps the last 50
    (status, text) in `messages`, calloc and free; and the logger, which
    the caller keeps alive as long as the instance."""
    def keep(component, instance, status, category, message):
        # Addresses, read without trusting them (the arguments of the
        # format are out of ctypes' reach: FMI 1.0 gives no environment
        # through which the core's formatting logger could route them).
        messages.append((status, read_string(message)))
        del messages[:-50]

    logger = FMI1_LOGGER(keep)
    callbacks = struct_type()
    callbacks.logger = ctypes.cast(logger, fmi1CallbackLoggerTYPE)
    callbacks.allocateMemory = ctypes.cast(calloc, fmi1CallbackAllocateMemoryTYPE)
    callbacks.freeMemory = ctypes.cast(free, fmi1CallbackFreeMemoryTYPE)
    return callbacks, logger
