"""pytest plugin for the AddressSanitizer run of tests/fmu (cmake/hardening.cmake).

fmpy hands FMUs libc's calloc/free, looked up in libc itself, so blocks an
FMU allocates through its callbacks would bypass the preloaded sanitizer
runtime: no redzones, no use-after-free or double-free detection in the
FMUs' heap. Loaded with `pytest -p asan_fmpy`, before any test module
imports the callbacks, this points fmpy's calloc/free at the process-wide
symbols, which the preloaded ASan runtime provides.
"""

import ctypes
import os
import sys

if "libasan" not in os.environ.get("LD_PRELOAD", ""):
    raise RuntimeError("asan_fmpy is meant for a run with the ASan runtime in LD_PRELOAD")
if "fmu_driver" in sys.modules:
    raise RuntimeError("asan_fmpy must be loaded before tests/fmu/fmu_driver.py (pytest -p asan_fmpy)")

import fmpy  # noqa: E402  (imports fmpy.fmi1, fmpy.fmi2, fmpy.simulation)
import fmpy.fmi1  # noqa: E402
import fmpy.fmi2  # noqa: E402
import fmpy.simulation  # noqa: E402

_process = ctypes.CDLL(None)  # global symbol lookup: the preloaded runtime comes first
calloc = _process.calloc
calloc.argtypes = [ctypes.c_size_t, ctypes.c_size_t]
calloc.restype = ctypes.c_void_p
free = _process.free
free.argtypes = [ctypes.c_void_p]

for _module in (fmpy, fmpy.fmi1, fmpy.fmi2, fmpy.simulation):
    _module.calloc = calloc
    _module.free = free
# The default callbacks keep ctypes wrappers; these module globals keep the
# new ones alive.
_fmi1_alloc = fmpy.fmi1.fmi1CallbackAllocateMemoryTYPE(calloc)
_fmi1_free = fmpy.fmi1.fmi1CallbackFreeMemoryTYPE(free)
fmpy.fmi1.defaultCallbacks.allocateMemory = _fmi1_alloc
fmpy.fmi1.defaultCallbacks.freeMemory = _fmi1_free
_fmi2_alloc = fmpy.fmi2.fmi2CallbackAllocateMemoryTYPE(calloc)
_fmi2_free = fmpy.fmi2.fmi2CallbackFreeMemoryTYPE(free)
fmpy.fmi2.defaultCallbacks.allocateMemory = _fmi2_alloc
fmpy.fmi2.defaultCallbacks.freeMemory = _fmi2_free
