"""CVode (SUNDIALS' BDF integrator) from fmpy's bundled SUNDIALS libraries.

The Model Exchange wrapper integrates stiff models with CVode, the solver
fmpy and OMSimulator use for Model Exchange FMUs. fmpy ships SUNDIALS 7 as
shared libraries (``fmpy.sundials``); this module binds the functions the
wrapper calls, with their C signatures, for the Python engine, and hands
their addresses to the compiled core (``Sundials.table``), so that both
engines drive the same CVode with the same calls and get the same bits.

A ``CVodeRun`` holds one integrator: its context, state vector, tolerances,
dense matrix and linear solver. Its pointers live in the Model Exchange
wrapper's shared struct (``cv_*`` fields), so that whichever engine steps
next finds, and if need be frees, what the other made. SUNDIALS' error
handlers are cleared: failures come back as return codes and the wrapper
reports them in one line, nothing is printed.
"""

from __future__ import annotations

import ctypes
import threading
from ctypes import CFUNCTYPE, POINTER, Structure, byref, c_double, c_int, c_int64, c_long, c_void_p

CV_BDF = 2
CV_ONE_STEP = 2
CV_TSTOP_RETURN = 1

# The functions, in the order of the compiled core's cw_sundials table.
_SIGNATURES = (
    ("core", "SUNContext_Create", c_int, [c_int, POINTER(c_void_p)]),
    ("core", "SUNContext_Free", c_int, [POINTER(c_void_p)]),
    ("core", "SUNContext_ClearErrHandlers", c_int, [c_void_p]),
    ("core", "N_VGetArrayPointer", POINTER(c_double), [c_void_p]),
    ("core", "N_VDestroy", None, [c_void_p]),
    ("core", "SUNMatDestroy", None, [c_void_p]),
    ("core", "SUNLinSolFree", c_int, [c_void_p]),
    ("nvec", "N_VNew_Serial", c_void_p, [c_int64, c_void_p]),
    ("mat", "SUNDenseMatrix", c_void_p, [c_int64, c_int64, c_void_p]),
    ("ls", "SUNLinSol_Dense", c_void_p, [c_void_p, c_void_p, c_void_p]),
    ("cvode", "CVodeCreate", c_void_p, [c_int, c_void_p]),
    ("cvode", "CVodeInit", c_int, [c_void_p, c_void_p, c_double, c_void_p]),
    ("cvode", "CVodeReInit", c_int, [c_void_p, c_double, c_void_p]),
    ("cvode", "CVodeSVtolerances", c_int, [c_void_p, c_double, c_void_p]),
    ("cvode", "CVodeSetLinearSolver", c_int, [c_void_p, c_void_p, c_void_p]),
    ("cvode", "CVodeSetUserData", c_int, [c_void_p, c_void_p]),
    ("cvode", "CVodeSetStopTime", c_int, [c_void_p, c_double]),
    ("cvode", "CVode", c_int, [c_void_p, c_double, c_void_p, POINTER(c_double), c_int]),
    ("cvode", "CVodeGetDky", c_int, [c_void_p, c_double, c_int, c_void_p]),
    ("cvode", "CVodeGetNumRhsEvals", c_int, [c_void_p, POINTER(c_long)]),
    ("cvode", "CVodeGetNumLinRhsEvals", c_int, [c_void_p, POINTER(c_long)]),
    ("cvode", "CVodeGetNumErrTestFails", c_int, [c_void_p, POINTER(c_long)]),
    ("cvode", "CVodeGetNumNonlinSolvConvFails", c_int, [c_void_p, POINTER(c_long)]),
    ("cvode", "CVodeFree", None, [POINTER(c_void_p)]),
)

RHS = CFUNCTYPE(c_int, c_double, c_void_p, c_void_p, c_void_p)  # CVRhsFn


class Table(Structure):
    """cw_sundials in src_c/master/cw_me.c: the addresses of the functions above."""

    _fields_ = [(name, c_void_p) for _, name, _, _ in _SIGNATURES]


class Sundials:
    """fmpy's SUNDIALS functions, bound with their signatures."""

    def __init__(self):
        from fmpy.sundials import libraries  # loads the five libraries

        libs = {"core": libraries.sundials_core, "nvec": libraries.sundials_nvecserial,
                "mat": libraries.sundials_sunmatrixdense, "ls": libraries.sundials_sunlinsoldense,
                "cvode": libraries.sundials_cvode}
        self.table = Table()
        for lib, name, restype, argtypes in _SIGNATURES:
            f = libs[lib][name]  # a function object of its own: fmpy keeps its own signatures
            f.restype, f.argtypes = restype, argtypes
            setattr(self, name, f)
            setattr(self.table, name, ctypes.cast(f, c_void_p).value)


_sundials: list = []
_sundials_lock = threading.Lock()


def sundials() -> Sundials | None:
    """The bound SUNDIALS functions, or None where fmpy has none for this platform."""
    with _sundials_lock:
        if not _sundials:
            try:
                _sundials.append(Sundials())
            except Exception:  # fmpy raises a bare Exception for another SUNDIALS version
                _sundials.append(None)
        return _sundials[0]


def problem() -> str | None:
    """Why CVode cannot be used here, or None."""
    if sundials() is None:
        import fmpy

        return (f"fmpy {fmpy.__version__} has no SUNDIALS 7 libraries for this platform "
                f"(fmpy.sundials), which the stiff solver cvode uses")
    return None


class CVodeRun:
    """One CVode integrator on the Model Exchange wrapper's shared struct `me`
    (its cv_* fields), made by the Python engine with a Python right-hand side."""

    def __init__(self, me, rhs):
        self.sun = sundials()
        self.me = me
        self.rhs = RHS(rhs)  # kept alive as long as CVode may call it

    def create(self, t: float, x, atol) -> int:
        """Make the integrator at (t, x) with tolerances rtol and atol (per state); 0 or a CVode flag."""
        sun, me = self.sun, self.me
        free(me)
        ctx = c_void_p()
        if sun.SUNContext_Create(0, byref(ctx)):
            return -1
        me.cv_ctx = ctx.value
        sun.SUNContext_ClearErrHandlers(ctx)
        n = me.n
        me.cv_y = sun.N_VNew_Serial(n, ctx)
        me.cv_abstol = sun.N_VNew_Serial(n, ctx)
        me.cv_dky = sun.N_VNew_Serial(n, ctx)
        me.cv_A = sun.SUNDenseMatrix(n, n, ctx)
        me.cv_LS = sun.SUNLinSol_Dense(me.cv_y, me.cv_A, ctx)
        me.cv_mem = sun.CVodeCreate(CV_BDF, ctx)
        if not (me.cv_y and me.cv_abstol and me.cv_dky and me.cv_A and me.cv_LS and me.cv_mem):
            return -1
        self.put(me.cv_y, x)
        self.put(me.cv_abstol, atol)
        flag = sun.CVodeInit(me.cv_mem, ctypes.cast(self.rhs, c_void_p), t, me.cv_y)
        flag = flag or sun.CVodeSVtolerances(me.cv_mem, me.rtol, me.cv_abstol)
        flag = flag or sun.CVodeSetLinearSolver(me.cv_mem, me.cv_LS, me.cv_A)
        return flag

    def reinit(self, t: float, x, atol) -> int:
        sun, me = self.sun, self.me
        self.put(me.cv_y, x)
        self.put(me.cv_abstol, atol)
        return sun.CVodeReInit(me.cv_mem, t, me.cv_y) or sun.CVodeSVtolerances(me.cv_mem, me.rtol, me.cv_abstol)

    def put(self, vector, values) -> None:
        data = self.sun.N_VGetArrayPointer(vector)
        for i, v in enumerate(values):
            data[i] = v

    def get(self, vector) -> list[float]:
        return self.sun.N_VGetArrayPointer(vector)[:self.me.n]

    def step(self, t_stop: float) -> tuple[int, float]:
        """One internal step toward t_stop (never past it): (flag, time reached)."""
        sun, me = self.sun, self.me
        reached = c_double(0.0)
        flag = sun.CVodeSetStopTime(me.cv_mem, t_stop)
        if flag == 0:
            flag = sun.CVode(me.cv_mem, t_stop, me.cv_y, byref(reached), CV_ONE_STEP)
        return flag, reached.value

    def dense(self, t: float) -> list[float]:
        """The solution at t inside the last step (CVodeGetDky, k = 0)."""
        me = self.me
        if self.sun.CVodeGetDky(me.cv_mem, t, 0, me.cv_dky):
            return [float("nan")] * me.n
        return self.get(me.cv_dky)

    def failures(self) -> int:
        """Steps CVode failed so far (error test and nonlinear convergence)."""
        me = self.me
        if not me.cv_mem:
            return 0
        a, b = c_long(), c_long()
        self.sun.CVodeGetNumErrTestFails(me.cv_mem, byref(a))
        self.sun.CVodeGetNumNonlinSolvConvFails(me.cv_mem, byref(b))
        return a.value + b.value


def free(me) -> None:
    """Free the integrator of the struct `me` (whichever engine made it)."""
    sun = sundials()
    if sun is None:
        return
    if me.cv_mem:
        mem = c_void_p(me.cv_mem)
        sun.CVodeFree(byref(mem))
    if me.cv_LS:
        sun.SUNLinSolFree(me.cv_LS)
    if me.cv_A:
        sun.SUNMatDestroy(me.cv_A)
    for name in ("cv_y", "cv_abstol", "cv_dky"):
        if getattr(me, name):
            sun.N_VDestroy(getattr(me, name))
    if me.cv_ctx:
        ctx = c_void_p(me.cv_ctx)
        sun.SUNContext_Free(byref(ctx))
    for name in ("cv_mem", "cv_LS", "cv_A", "cv_y", "cv_abstol", "cv_dky", "cv_ctx"):
        setattr(me, name, None)
    me.cv_owner = 0
