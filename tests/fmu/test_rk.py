"""The shared Runge-Kutta integrator (src_c/runtime/cw_rk.c) alone, through
libcw_rk_probe.so (in CW_BUILD_DIR, default build/) and ctypes: the
Dormand-Prince 5(4) pair (the default of cw_rk_init) and Dormand-Prince
8(5,3) (DOP853), each checked for its order, its dense output, landing and
failures, and the FMU's `integrator` parameter for the period of the free
pendulum."""

from __future__ import annotations

import ctypes as C
import math
import random
from fractions import Fraction

import numpy as np
import pytest

from cwtest import BUILD_DIR

MAXN = 8  # CW_RK_MAXN
MAXSTAGES = 16  # CW_RK_MAXSTAGES
AUTO, DP54, DOP853 = range(3)  # cw_rk_method
OK, STEP_TOO_SMALL, TOO_MANY_STEPS, NONFINITE, STOPPED = range(5)

Vec = C.c_double * MAXN


class Rk(C.Structure):
    """cw_rk from cw_rk.h, field by field."""

    _fields_ = [
        ("n", C.c_int),
        ("rtol", C.c_double),
        ("atol", C.c_double),
        ("h_max", C.c_double),
        ("max_steps", C.c_long),
        ("t0", C.c_double),
        ("h", C.c_double),
        ("x0", Vec),
        ("x1", Vec),
        ("k", Vec * MAXSTAGES),
        ("rcont", Vec * 8),
        ("n_accepted", C.c_long),
        ("n_rejected", C.c_long),
        ("n_rhs", C.c_long),
        ("method", C.c_int),
        ("dense_ready", C.c_int),
        ("f", C.c_void_p),
        ("ctx", C.c_void_p),
        ("atolv", C.c_void_p),
        ("stiffness_test", C.c_int),
        ("h_lambda", C.c_double),
        ("y_last", Vec),
    ]


RHS = C.CFUNCTYPE(None, C.c_void_p, C.c_double, C.POINTER(C.c_double), C.POINTER(C.c_double))
OBSERVER = C.CFUNCTYPE(C.c_int, C.c_void_p, C.POINTER(Rk))


@pytest.fixture(scope="module")
def lib():
    path = BUILD_DIR / "libcw_rk_probe.so"
    if not path.exists():
        pytest.fail(f"{path} is missing: build the cw_rk_probe target (set CW_BUILD_DIR)")
    return load_probe(path)


def load_probe(path):
    lib = C.CDLL(str(path))
    lib.cw_rk_init.argtypes = [C.POINTER(Rk), C.c_int, C.c_double, C.c_double, C.c_double]
    lib.cw_rk_init.restype = None
    lib.cw_rk_advance.argtypes = [
        C.POINTER(Rk), RHS, C.c_void_p, C.POINTER(C.c_double), C.c_double,
        C.POINTER(C.c_double), C.POINTER(C.c_double), OBSERVER, C.c_void_p]
    lib.cw_rk_advance.restype = C.c_int
    lib.cw_rk_dense.argtypes = [C.POINTER(Rk), C.c_double, C.POINTER(C.c_double)]
    lib.cw_rk_dense.restype = None
    lib.cw_rk_single_step.argtypes = [
        C.c_int, RHS, C.c_void_p, C.c_double, C.POINTER(C.c_double), C.c_double,
        C.POINTER(C.c_double)]
    lib.cw_rk_single_step.restype = None
    lib.cw_rk_single_step_with.argtypes = [C.c_int] + lib.cw_rk_single_step.argtypes
    lib.cw_rk_single_step_with.restype = None
    lib.cw_rk_choose.argtypes = [C.c_int, C.c_double]
    lib.cw_rk_choose.restype = C.c_int
    return lib


class Problem:
    """A right-hand side that records the times and points it is evaluated
    at."""

    def __init__(self, n, f):
        self.n = n
        self.times: list[float] = []
        self.points: list[list[float]] = []

        def rhs(ctx, t, x, dx):
            self.times.append(t)
            self.points.append([x[i] for i in range(n)])
            y = f(t, self.points[-1])
            for i in range(n):
                dx[i] = y[i]

        self.c = RHS(rhs)


def decay():
    return Problem(1, lambda t, x: [-x[0]])


def oscillator():
    return Problem(2, lambda t, x: [x[1], -x[0]])


def pendulum():
    return Problem(2, lambda t, x: [x[1], -9.81 * math.sin(x[0])])


def fixed_steps(lib, prob, x0, t_end, n_steps, method=DP54):
    x, out = Vec(*x0), Vec()
    h = t_end / n_steps
    for k in range(n_steps):
        if method == DP54:
            lib.cw_rk_single_step(prob.n, prob.c, None, k * h, x, h, out)
        else:
            lib.cw_rk_single_step_with(method, prob.n, prob.c, None, k * h, x, h, out)
        x[:] = out[:]
    return np.array(x[: prob.n])


def advance(lib, prob, x0, t_start, t_end, rtol, atol, h_max=0.0, rk=None, h_next=0.0,
            observer=None, max_steps=None, method=DP54):
    rk = rk or Rk()
    lib.cw_rk_init(C.byref(rk), prob.n, rtol, atol, h_max)
    assert rk.method == DP54
    rk.method = method
    if max_steps is not None:
        rk.max_steps = max_steps
    x = Vec(*x0)
    t = C.c_double(t_start)
    h = C.c_double(h_next)
    res = lib.cw_rk_advance(C.byref(rk), prob.c, None, C.byref(t), t_end, x, C.byref(h),
                            observer or OBSERVER(), None)
    return res, t.value, np.array(x[: prob.n]), h.value, rk


def slope(hs, errors):
    return np.polyfit(np.log(hs), np.log(errors), 1)[0]


# ---------------------------------------------------------------- orders


def test_order_5_on_decay(lib):
    counts = [8, 16, 32, 64]
    errors = [abs(fixed_steps(lib, decay(), [1.0], 1.0, n)[0] - math.exp(-1)) for n in counts]
    assert slope(1.0 / np.array(counts), errors) == pytest.approx(5, abs=0.3)


def test_order_5_on_harmonic_oscillator(lib):
    counts = [8, 16, 32, 64]
    T = 2 * math.pi
    errors = [np.max(np.abs(fixed_steps(lib, oscillator(), [1.0, 0.0], T, n) - [1.0, 0.0]))
              for n in counts]
    assert slope(T / np.array(counts), errors) == pytest.approx(5, abs=0.3)


def _one_step(lib, prob, x0, h, method=DP54):
    """Exactly one accepted step [0, h] (tolerances that accept anything).
    DOP853 builds its dense output with `prob`'s right-hand side on first
    use: keep `prob` alive until then."""
    res, t, x1, _, rk = advance(lib, prob, x0, 0.0, h, 1e6, 1e6, h_next=h, method=method)
    assert res == OK and t == h and rk.n_accepted == 1 and rk.n_rejected == 0
    return rk, x1


def _dense(lib, rk, t, n):
    out = Vec()
    lib.cw_rk_dense(C.byref(rk), t, out)
    return np.array(out[:n])


CASES = [
    ("decay", decay, [1.0], lambda t: [math.exp(-t)]),
    ("oscillator", oscillator, [1.0, 0.0], lambda t: [math.cos(t), -math.sin(t)]),
]


@pytest.mark.parametrize("name, make, x0, exact", CASES, ids=[c[0] for c in CASES])
def test_dense_output_local_error_is_order_5(lib, name, make, x0, exact):
    """Shampine's continuous extension of DOPRI5 is of order 4: its local
    error at the mid-point of a step is O(h^5), while the step's own end
    point is O(h^6)."""
    hs = np.array([0.2, 0.1, 0.05, 0.025])
    mid, end = [], []
    for h in hs:
        rk, x1 = _one_step(lib, make(), x0, h)
        mid.append(np.max(np.abs(_dense(lib, rk, h / 2, len(x0)) - exact(h / 2))))
        end.append(np.max(np.abs(x1 - exact(h))))
    assert slope(hs, mid) == pytest.approx(5, abs=0.3)
    assert slope(hs, end) == pytest.approx(6, abs=0.3)


def test_dense_output_matches_step_ends(lib):
    """The interpolant passes through x0 and x1 with slopes f(x0) and f(x1),
    so it is C1 from one step to the next."""
    h = 0.3
    rk, x1 = _one_step(lib, pendulum(), [1.0, 0.2], h)
    assert np.array_equal(_dense(lib, rk, 0.0, 2), [1.0, 0.2])
    assert np.allclose(_dense(lib, rk, h, 2), x1, rtol=0, atol=4e-16)
    eps = 1e-6
    for t, x in [(0.0, np.array([1.0, 0.2])), (h, x1)]:
        slope_ = (_dense(lib, rk, t + eps, 2) - _dense(lib, rk, t - eps, 2)) / (2 * eps)
        f = np.array([x[1], -9.81 * math.sin(x[0])])
        assert np.allclose(slope_, f, rtol=0, atol=1e-8)


# ---------------------------------------------------------------- adaptive


@pytest.mark.parametrize("rtol", [1e-6, 1e-8, 1e-10, 1e-12])
def test_adaptive_decay_within_a_few_rtol(lib, rtol):
    """Measured: relative error at t = 5 is 1.1-1.3 rtol."""
    res, t, x, _, _ = advance(lib, decay(), [1.0], 0.0, 5.0, rtol, 1e-3 * rtol)
    assert res == OK and t == 5.0
    assert abs(x[0] / math.exp(-5.0) - 1) <= 3 * rtol


@pytest.mark.parametrize("rtol", [1e-6, 1e-8, 1e-10, 1e-12])
def test_adaptive_oscillator_within_a_few_rtol(lib, rtol):
    """Measured: 0.75 rtol after one period, growing linearly (7.5 rtol after
    ten); asserted: 3 rtol after one period, 1 rtol per period over ten."""
    for periods, bound in [(1, 3 * rtol), (10, 10 * rtol)]:
        T = 2 * math.pi * periods
        res, t, x, _, _ = advance(lib, oscillator(), [1.0, 0.0], 0.0, T, rtol, 1e-3 * rtol)
        assert res == OK and t == T
        assert np.max(np.abs(x - [1.0, 0.0])) <= bound


# ---------------------------------------------------------------- landing


def test_lands_exactly_and_never_evaluates_past_t_end(lib):
    """Successive calls with irregular ends, the step suggestion carried: each
    returns with t == t_end bit for bit, and no stage is evaluated outside
    [t, t_end]."""
    rng = random.Random(5)
    prob = pendulum()
    x = [1.0, 0.0]
    t, h_next = 0.0, 0.0
    worst_over = 0.0
    for k in range(300):
        t_end = t + rng.choice([rng.uniform(1e-6, 1e-3), rng.uniform(0.01, 0.5), 10 ** rng.uniform(-12, 1)])
        prob.times.clear()
        res, t_new, x_new, h_next, _ = advance(lib, prob, x, t, t_end, 1e-10, 1e-12, h_next=h_next)
        assert res == OK, (k, t, t_end)
        assert t_new == t_end
        assert min(prob.times) >= t
        worst_over = max(worst_over, max(prob.times) - t_end)
        t, x = t_new, list(x_new)
    assert worst_over <= 0.0, f"right-hand side evaluated {worst_over:.3g} s past t_end"


# Pairs where t0 + (t1 - t0) rounds to the double above t1.
ROUNDS_UP = [(0.14015341763253203, 0.6838829735587687), (55.65787745692198, 216.377291768125)]


@pytest.mark.parametrize("h_next", [0.0, 1e3])
def test_last_step_stays_inside_where_t_plus_h_rounds_up(lib, h_next):
    """When the last step starts below t_end/2, t + (t_end - t) can exceed
    t_end by an ulp; the last stages must still be evaluated at t_end. With
    h_next = 1e3 the whole span is one step."""
    for t0, t1 in ROUNDS_UP:
        assert t0 + (t1 - t0) > t1
        prob = decay()
        res, t, _, _, _ = advance(lib, prob, [1.0], t0, t1, 1e-3, 1e-6, h_next=h_next)
        assert res == OK and t == t1
        assert max(prob.times) == t1 and min(prob.times) == t0


def test_tiny_final_interval_is_integrated(lib):
    """A span of one ulp is a step like any other, not a step-size underflow."""
    for t0 in [1.0, 5.0, 1234.5]:
        t1 = math.nextafter(t0, math.inf)
        res, t, x, _, _ = advance(lib, decay(), [1.0], t0, t1, 1e-10, 1e-12)
        assert res == OK and t == t1
        assert x[0] == pytest.approx(1.0 - (t1 - t0), abs=1e-15)


def test_empty_interval_is_a_no_op(lib):
    prob = decay()
    res, t, x, _, rk = advance(lib, prob, [2.0], 3.0, 3.0, 1e-8, 1e-10)
    assert (res, t, x[0], rk.n_rhs, len(prob.times)) == (OK, 3.0, 2.0, 0, 0)
    res, t, x, _, _ = advance(lib, prob, [2.0], 3.0, 2.0, 1e-8, 1e-10)
    assert (res, t, x[0]) == (OK, 3.0, 2.0)


def test_h_max_and_statistics(lib):
    steps = []

    def observe(ctx, rk):
        steps.append((rk.contents.t0, rk.contents.h))
        return 0

    prob = oscillator()
    obs = OBSERVER(observe)
    res, t, _, _, rk = advance(lib, prob, [1.0, 0.0], 0.0, 3.0, 1e-6, 1e-9, h_max=0.01, observer=obs)
    assert res == OK and t == 3.0
    assert len(steps) == rk.n_accepted >= 300
    assert max(h for _, h in steps) <= 0.01
    # The accepted steps tile [0, 3] without gaps.
    for (t0, h), (t0_next, _) in zip(steps, steps[1:]):
        assert t0_next == t0 + h
    assert steps[0][0] == 0.0
    # First f, one probe of the initial step size, then 6 per attempted step (FSAL).
    assert rk.n_rhs == len(prob.times) == 2 + 6 * (rk.n_accepted + rk.n_rejected)


def test_observer_can_stop(lib):
    seen = []

    def observe(ctx, rk):
        seen.append(rk.contents.t0 + rk.contents.h)
        return len(seen) == 3

    res, t, x, _, rk = advance(lib, decay(), [1.0], 0.0, 10.0, 1e-8, 1e-10,
                               observer=OBSERVER(observe))
    assert res == STOPPED and rk.n_accepted == 3
    assert t == seen[-1] < 10.0
    assert x[0] == pytest.approx(math.exp(-t), rel=1e-7)


def test_failures_are_reported(lib):
    # y' = y^2 from 1 blows up at t = 1.
    res, t, x, _, _ = advance(lib, Problem(1, lambda t, x: [x[0] * x[0]]), [1.0], 0.0, 2.0, 1e-8, 1e-10)
    assert res in (STEP_TOO_SMALL, NONFINITE) and t < 1.001
    res, t, _, _, rk = advance(lib, oscillator(), [1.0, 0.0], 0.0, 100.0, 1e-10, 1e-12, max_steps=50)
    assert res == TOO_MANY_STEPS and rk.n_accepted + rk.n_rejected == 50 and t < 100.0
    res, _, _, _, _ = advance(lib, Problem(1, lambda t, x: [math.nan]), [1.0], 0.0, 1.0, 1e-8, 1e-10)
    assert res == NONFINITE


# ---------------------------------------------------------------- DOP853
# Dormand-Prince 8(5,3): rk.method = DOP853 after cw_rk_init.


def test_choice_of_the_pair(lib):
    assert lib.cw_rk_choose(DP54, 1e-12) == DP54
    assert lib.cw_rk_choose(DOP853, 1e-2) == DOP853
    assert lib.cw_rk_choose(AUTO, 1e-6) == DOP853
    assert lib.cw_rk_choose(AUTO, 1e-10) == DOP853
    assert lib.cw_rk_choose(AUTO, 2e-6) == DP54
    assert lib.cw_rk_choose(AUTO, 1e-3) == DP54


def test_order_8_on_decay(lib):
    """Relative error at t = 4; measured slope 8.14."""
    counts = [4, 6, 8, 12, 16]
    errors = [abs(fixed_steps(lib, decay(), [1.0], 4.0, n, DOP853)[0] / math.exp(-4.0) - 1)
              for n in counts]
    assert slope(4.0 / np.array(counts), errors) == pytest.approx(8, abs=0.3)


def test_order_8_on_harmonic_oscillator(lib):
    """Measured slope 7.99."""
    counts = [8, 12, 16, 24, 32]
    T = 2 * math.pi
    errors = [np.max(np.abs(fixed_steps(lib, oscillator(), [1.0, 0.0], T, n, DOP853) - [1.0, 0.0]))
              for n in counts]
    assert slope(T / np.array(counts), errors) == pytest.approx(8, abs=0.3)


def test_order_8_on_pendulum(lib):
    """Against a fixed-step solution with 1024 steps; measured slope 7.80
    (the nonlinear problem's error constants vary along the arc: 7.4-9.0
    over other spans and step ranges)."""
    counts = [8, 12, 16, 24]
    T = 1.3
    ref = fixed_steps(lib, pendulum(), [1.0, 0.3], T, 1024, DOP853)
    errors = [np.max(np.abs(fixed_steps(lib, pendulum(), [1.0, 0.3], T, n, DOP853) - ref))
              for n in counts]
    assert slope(T / np.array(counts), errors) == pytest.approx(8, abs=0.5)


@pytest.mark.parametrize("name, make, x0, exact", CASES, ids=[c[0] for c in CASES])
def test_dop853_dense_output_is_order_7(lib, name, make, x0, exact):
    """The continuous extension of DOP853 is of order 7: its local error
    inside a step is O(h^8) (measured slopes 7.92 and 8.02 at theta = 0.3,
    0.5, 0.7), while the step's end point is O(h^9) (measured 8.4-8.8 at
    these large steps; smaller ones reach round-off)."""
    hs = np.array([0.8, 0.4, 0.2, 0.1])
    inside = []
    for h in hs:
        prob = make()
        rk, _ = _one_step(lib, prob, x0, h, DOP853)
        inside.append(max(np.max(np.abs(_dense(lib, rk, th * h, len(x0)) - exact(th * h)))
                          for th in (0.3, 0.5, 0.7)))
    assert slope(hs, inside) == pytest.approx(8, abs=0.3)
    hs_end = np.array([1.2, 0.8, 0.6, 0.4])
    end = []
    for h in hs_end:
        _, x1 = _one_step(lib, make(), x0, h, DOP853)
        end.append(np.max(np.abs(x1 - exact(h))))
    assert 8.3 <= slope(hs_end, end) <= 9.3


U = Fraction(1, 2**53)  # unit roundoff of binary64


class Rounded:
    """A binary64 computation followed in exact arithmetic: `exact` is its
    value without rounding, `err` a bound on |computed - exact|. Each + - *
    rounds once, fl(a op b) = (a op b)(1 + d) with |d| <= U, so the result
    inherits the operands' bounds (second-order terms kept) plus U times its
    own magnitude. Adding an exact zero is exact. The bound holds whether or
    not the compiler fuses a multiply-add (one rounding instead of two)."""

    def __init__(self, exact, err=Fraction(0)):
        self.exact, self.err = Fraction(exact), err

    @staticmethod
    def constant(c):
        """A tableau coefficient: scipy's double for a real constant that the
        C source spells as its own literal; both are within U |c| of the
        constant, so within 2 U |c| of each other."""
        return Rounded(c, 2 * U * abs(Fraction(c)))

    def _rounded(self, exact, err):
        return Rounded(exact, err + U * (abs(exact) + err))

    def __add__(self, o):
        if o.exact == 0 and o.err == 0:
            return self
        return self._rounded(self.exact + o.exact, self.err + o.err)

    def __neg__(self):
        return Rounded(-self.exact, self.err)

    def __sub__(self, o):
        return self + -o

    def __mul__(self, o):
        err = abs(self.exact) * o.err + abs(o.exact) * self.err + self.err * o.err
        return self._rounded(self.exact * o.exact, err)

    def __truediv__(self, o):  # only by an exact divisor here
        assert o.err == 0
        return self._rounded(self.exact / o.exact, self.err / abs(o.exact))


def _dot(coefficients, values):
    """sum_j c_j v_j summed left to right, as cw_rk.c does."""
    total = Rounded(0)
    for c, v in zip(coefficients, values):
        total = total + Rounded.constant(c) * v
    return total


def test_dop853_is_scipys_method_to_rounding(lib):
    """An independent check of the tableau and the dense output: one step of
    cw_rk.c must be scipy.integrate.DOP853's method (its coefficients
    DOP853.A, B, C, A_EXTRA, C_EXTRA, D) up to the C code's own rounding.
    Every stage's time and point, the new point x1 and the dense output at
    five thetas are compared with scipy's formulas evaluated exactly
    (fractions) on the stage derivatives k[0..15] that the C code computed,
    within the rounding bound of the C code's order of operations (Rounded).

    Not against the output of scipy's solver: it evaluates these sums with
    numpy dot products (OpenBLAS) whose summation order depends on the CPU
    kernel. Measured on one AVX-512 machine, the dense output at theta 0.7
    (component w) is -0x1.7ca4416bc7556p+0 with OPENBLAS_CORETYPE=Haswell,
    ...7548 with SkylakeX, ...7543 with Sandybridge or Prescott: 19 ulps
    (4.2e-15) apart; cw_rk.c gives ...7543, and the step in exact
    arithmetic (mpmath, 60 digits) is 1.8 ulps below it."""
    from scipy.integrate import DOP853 as ScipyDOP853

    prob = pendulum()
    x0, h = [1.0, 0.2], 0.3
    rk, x1 = _one_step(lib, prob, x0, h, DOP853)
    assert (rk.t0, rk.h) == (0.0, h)
    thetas = (0.1, 0.3, 0.5, 0.7, 0.9)
    dense = [_dense(lib, rk, th * h, 2) for th in thetas]
    # f(t0, x0), stages 1..11, f(t0 + h, x1), the dense output's 13..15
    assert len(prob.times) == 16 and prob.points[12] == list(x1)

    sp = ScipyDOP853
    # Stage s is at t0 + nodes[s] h, x0 + h sum_j weights[s][j] k[j]; x1 is "stage 12".
    nodes = list(sp.C) + [1.0] + list(sp.C_EXTRA)
    weights = [sp.A[s][:s] for s in range(12)] + [sp.B] + [
        sp.A_EXTRA[s - 13][:s] for s in range(13, 16)]
    t0, hr = Rounded(rk.t0), Rounded(rk.h)
    k = [[Rounded(rk.k[s][i]) for s in range(16)] for i in range(2)]
    for s in range(1, 16):
        t, y = prob.times[s], prob.points[s]
        when = t0 + Rounded.constant(nodes[s]) * hr
        assert abs(Fraction(t) - when.exact) <= when.err, f"time of stage {s}"
        for i in range(2):
            point = Rounded(x0[i]) + hr * _dot(weights[s], k[i][:s])
            assert abs(Fraction(y[i]) - point.exact) <= point.err, f"stage {s}, component {i}"

    for th, got in zip(thetas, dense):
        theta = (Rounded(th * h) - t0) / hr
        theta1 = Rounded(1) - theta
        for i in range(2):
            # cw_rk.c's operations (prepare_dense8, dense8): the rounding bound
            dx = Rounded(x1[i]) - Rounded(x0[i])
            r = [Rounded(x0[i]), dx, hr * k[i][0] - dx]
            r.append(dx - hr * k[i][12] - r[2])
            r += [hr * _dot(sp.D[j], k[i]) for j in range(4)]
            tail = r[4] + theta * (r[5] + theta1 * (r[6] + theta * r[7]))
            c_code = r[0] + theta * (r[1] + theta1 * (r[2] + theta * (r[3] + theta1 * tail)))
            # scipy's polynomial (Dop853DenseOutput), exactly
            x, hx, kx = theta.exact, hr.exact, [v.exact for v in k[i]]
            dy = Fraction(x1[i]) - Fraction(x0[i])
            F = [dy, hx * kx[0] - dy, 2 * dy - hx * (kx[12] + kx[0])]
            F += [hx * sum(Fraction(d) * kx[s] for s, d in enumerate(row)) for row in sp.D]
            ref = Fraction(0)
            for j, f in enumerate(reversed(F)):
                ref = (ref + f) * (x if j % 2 == 0 else 1 - x)
            ref += Fraction(x0[i])
            assert abs(Fraction(got[i]) - ref) <= c_code.err, f"theta {th}, component {i}"


def test_dop853_dense_output_matches_step_ends(lib):
    """Built on demand with 3 more right-hand sides; it passes through x0
    and x1 with slopes f(x0) and f(x1)."""
    h = 0.3
    prob = pendulum()
    rk, x1 = _one_step(lib, prob, [1.0, 0.2], h, DOP853)
    before = rk.n_rhs
    assert not rk.dense_ready
    assert np.array_equal(_dense(lib, rk, 0.0, 2), [1.0, 0.2])
    assert rk.dense_ready and rk.n_rhs == before + 3
    assert np.allclose(_dense(lib, rk, h, 2), x1, rtol=0, atol=4e-16)
    assert rk.n_rhs == before + 3  # built once
    eps = 1e-6
    for t, x in [(0.0, np.array([1.0, 0.2])), (h, x1)]:
        slope_ = (_dense(lib, rk, t + eps, 2) - _dense(lib, rk, t - eps, 2)) / (2 * eps)
        f = np.array([x[1], -9.81 * math.sin(x[0])])
        assert np.allclose(slope_, f, rtol=0, atol=1e-8)


def test_dop853_dense_output_inside_adaptive_steps(lib):
    """In the observer, at rtol 1e-12, the dense output is as good as the
    steps themselves: within 3e-12 of the exact oscillator everywhere."""
    worst = []
    out = Vec()

    def observe(ctx, rk):
        r = rk.contents
        for th in (0.25, 0.5, 0.75):
            t = r.t0 + th * r.h
            lib.cw_rk_dense(rk, t, out)
            worst.append(max(abs(out[0] - math.cos(t)), abs(out[1] + math.sin(t))))
        return 0

    prob = oscillator()
    res, t, _, _, rk = advance(lib, prob, [1.0, 0.0], 0.0, 2 * math.pi, 1e-12, 1e-15,
                               observer=OBSERVER(observe), method=DOP853)
    assert res == OK and len(worst) == 3 * rk.n_accepted
    assert max(worst) <= 3e-12


@pytest.mark.parametrize("rtol", [1e-6, 1e-8, 1e-10, 1e-12])
def test_dop853_adaptive_within_a_few_rtol(lib, rtol):
    res, t, x, _, _ = advance(lib, decay(), [1.0], 0.0, 5.0, rtol, 1e-3 * rtol, method=DOP853)
    assert res == OK and t == 5.0
    assert abs(x[0] / math.exp(-5.0) - 1) <= 3 * rtol
    for periods, bound in [(1, 3 * rtol), (10, 10 * rtol)]:
        T = 2 * math.pi * periods
        res, t, x, _, _ = advance(lib, oscillator(), [1.0, 0.0], 0.0, T, rtol, 1e-3 * rtol,
                                  method=DOP853)
        assert res == OK and t == T
        assert np.max(np.abs(x - [1.0, 0.0])) <= bound


def test_dop853_lands_exactly_and_never_evaluates_past_t_end(lib):
    """As for the 5(4) pair, with the dense output (whose extra stages lie
    inside the step) built after every step."""
    rng = random.Random(7)
    prob = pendulum()
    out = Vec()

    def observe(ctx, rk):
        lib.cw_rk_dense(rk, rk.contents.t0 + 0.5 * rk.contents.h, out)
        return 0

    obs = OBSERVER(observe)
    x, t, h_next = [1.0, 0.0], 0.0, 0.0
    for k in range(300):
        t_end = t + rng.choice([rng.uniform(1e-6, 1e-3), rng.uniform(0.01, 0.5), 10 ** rng.uniform(-12, 1)])
        prob.times.clear()
        res, t_new, x_new, h_next, _ = advance(lib, prob, x, t, t_end, 1e-10, 1e-12, h_next=h_next,
                                               observer=obs, method=DOP853)
        assert res == OK and t_new == t_end, (k, t, t_end)
        assert min(prob.times) >= t and max(prob.times) <= t_end
        t, x = t_new, list(x_new)
    for t0, t1 in ROUNDS_UP:
        prob = decay()
        res, t, _, _, _ = advance(lib, prob, [1.0], t0, t1, 1e-3, 1e-6, h_next=1e3, method=DOP853)
        assert res == OK and t == t1 and max(prob.times) == t1


def test_dop853_statistics_and_failures(lib):
    prob = oscillator()
    res, t, _, _, rk = advance(lib, prob, [1.0, 0.0], 0.0, 30.0, 1e-10, 1e-13, method=DOP853)
    assert res == OK and t == 30.0
    # First f, one probe for the first step, 11 stages per attempt and f at
    # the new point of each accepted step (the next step's first stage).
    assert rk.n_rhs == len(prob.times) == 2 + 11 * (rk.n_accepted + rk.n_rejected) + rk.n_accepted
    res, t, x, _, _ = advance(lib, Problem(1, lambda t, x: [x[0] * x[0]]), [1.0], 0.0, 2.0, 1e-8, 1e-10,
                              method=DOP853)
    assert res in (STEP_TOO_SMALL, NONFINITE) and t < 1.001
    res, _, _, _, rk = advance(lib, oscillator(), [1.0, 0.0], 0.0, 100.0, 1e-10, 1e-12, max_steps=5,
                               method=DOP853)
    assert res == TOO_MANY_STEPS and rk.n_accepted + rk.n_rejected == 5
    res, _, _, _, _ = advance(lib, Problem(1, lambda t, x: [math.nan]), [1.0], 0.0, 1.0, 1e-8, 1e-10,
                              method=DOP853)
    assert res == NONFINITE


EPS_HOYNG = 1.167245e-4  # Hoyng's clock at point C: L = g = 1, Q = 1/(2 eps)


def _evaluations_per_period(lib, method, rtol, amplitude, steps_per_period=7, periods=20,
                            dense=False):
    """Right-hand sides per period of the damped pendulum of Hoyng's clock,
    advanced as the Pendulum FMU is: one cw_rk_advance per communication
    step, the step suggestion carried."""
    prob = Problem(2, lambda t, x: [x[1], -math.sin(x[0]) - 2 * EPS_HOYNG * x[1]])
    out = Vec()

    def observe(ctx, rk):
        lib.cw_rk_dense(rk, rk.contents.t0 + 0.5 * rk.contents.h, out)
        return 0

    obs = OBSERVER(observe) if dense else OBSERVER()
    rk = Rk()
    lib.cw_rk_init(C.byref(rk), 2, rtol, 1e-2 * rtol, 0.0)
    rk.method = method
    x, t, h = Vec(amplitude, 0.0), C.c_double(0.0), C.c_double(0.0)
    H = 2 * math.pi / steps_per_period
    for k in range(steps_per_period * periods):
        assert lib.cw_rk_advance(C.byref(rk), prob.c, None, C.byref(t), (k + 1) * H, x, C.byref(h),
                                 obs, None) == OK
    return rk.n_rhs / periods


def test_dop853_needs_fewer_evaluations_at_rtol_1e_10(lib):
    """Hoyng's clock, 7 communication steps per period, rtol 1e-10: measured
    1081 right-hand sides per period with DP5(4), 260 with DOP853 (324 when
    the dense output is also built after every step)."""
    dp54 = _evaluations_per_period(lib, DP54, 1e-10, 0.05)
    dop853 = _evaluations_per_period(lib, DOP853, 1e-10, 0.05)
    dense = _evaluations_per_period(lib, DOP853, 1e-10, 0.05, dense=True)
    assert dop853 < dense < 0.35 * dp54


def test_auto_choice_saves_evaluations(lib):
    """One long advance over 20 free periods (no communication steps): from
    rtol 1e-6 down DOP853 needs fewer right-hand sides at small and large
    amplitudes; at 1e-5 and large swings DP5(4) is the cheaper one."""
    def per_period(method, rtol, amplitude):
        prob = pendulum()
        T = 2 * math.pi / math.sqrt(9.81)
        res, _, _, _, rk = advance(lib, prob, [amplitude, 0.0], 0.0, 20 * T, rtol, 1e-2 * rtol * amplitude,
                                   method=method)
        assert res == OK
        return rk.n_rhs / 20

    for amplitude in (0.05, 1.5):
        for rtol in (1e-6, 1e-8, 1e-10):
            assert lib.cw_rk_choose(AUTO, rtol) == DOP853
            assert per_period(DOP853, rtol, amplitude) < per_period(DP54, rtol, amplitude)
    assert lib.cw_rk_choose(AUTO, 1e-5) == DP54
    assert per_period(DP54, 1e-5, 1.5) < per_period(DOP853, 1e-5, 1.5)


# ---------------------------------------------------------------- FMUs


def _agm(a, b):
    for _ in range(40):
        a, b = 0.5 * (a + b), math.sqrt(a * b)
    return a


@pytest.mark.parametrize("amp_deg", [1, 10, 90, 135])
def test_pendulum_fmu_period_with_dop853(amp_deg):
    """The free period of the Pendulum FMU with integrator = 2 at rtol 1e-12
    against the AGM: within 1e-11 relative."""
    from cwtest import fmu_file
    from fmu_driver import Instance

    A = math.radians(amp_deg)
    T = 2 * math.pi * math.sqrt(1.0 / 9.81) / _agm(1.0, math.cos(A / 2))
    with Instance(fmu_file("Pendulum"), dict(Q=0, phi_start=A, rtol=1e-12, atol=1e-12 * A,
                                             integrator=DOP853)) as p:
        while p.get("tick_count") < 3:
            p.advance(T / 7)
        period = p.get("period")
    assert abs(period / T - 1) <= 1e-11, f"period {period!r} s, exact {T!r} s"


@pytest.mark.parametrize("model", ["Pendulum", "AveragedPendulum", "MechanismVibration"])
def test_integrator_parameter_range(model):
    from cwtest import fmu_file
    from fmu_driver import ERROR, Instance

    for value, status in [(-1, ERROR), (0, OK), (1, OK), (2, OK), (3, ERROR)]:
        with Instance(fmu_file(model), initialize=False) as p:
            v = p.vars["integrator"]
            assert (v.type, v.causality, v.variability, v.start) == ("Integer", "parameter", "fixed", "0")
            p.setup()
            p.enter_init()
            assert p.set(integrator=value) == status, p.log_text()
            if status == OK:
                assert p.exit_init() == OK
                p.advance(0.5, 4)


def test_integrator_travels_with_the_fmu_state():
    """The runtime serializes every variable, parameters included (the
    documented layout is unchanged: one more i32 in table order), so a state
    taken with integrator = 2 continues with DOP853 bit for bit in a fresh
    instance left at the default; an integrator outside [0, 2] in a state
    with a valid checksum is refused."""
    import struct

    from cwtest import fmu_file
    from fmu_driver import ERROR, Instance, state_checksum

    fmu = fmu_file("Pendulum")
    params = dict(Q=300.0, phi_start=0.4, rtol=1e-9, atol=1e-12, integrator=DOP853)

    def run(p, n):
        out = []
        for _ in range(n):
            p.advance(0.37)
            out.append(tuple(p.get_many(["phi", "w", "tick_time", "period"])))
        return out

    with Instance(fmu, params) as p:
        run(p, 10)
        state = p.get_state()
        data = p.serialize(state)
        p.free_state(state)
        t_saved = p.time
        first = run(p, 20)
    with Instance(fmu, dict(params, integrator=DP54)) as p:
        p.advance(0.37, 10)
        other = run(p, 20)
    assert other != first  # the pairs differ, so the comparison below means something
    with Instance(fmu, dict(rtol=0.1), name="fresh") as q:  # auto would pick DP5(4)
        st, state = q.deserialize(data)
        assert st == OK, q.log_text()
        assert q.set_state(state) == OK
        q.free_state(state)
        q.time = t_saved
        assert q.get("integrator") == DOP853
        assert run(q, 20) == first
        # Where the integrator sits in the layout: after the Reals before it.
        md = q.md
        off = 24 + 8
        for v in sorted(md.modelVariables, key=lambda v: v.valueReference):
            if v.name == "integrator":
                break
            off += 8 + (24 if v.type == "Real" and v.causality == "input" else 0) if v.type == "Real" else 4
        assert struct.unpack_from("<i", data, off)[0] == DOP853
        bad = bytearray(data)
        bad[off:off + 4] = struct.pack("<i", 3)
        bad[-8:] = state_checksum(bytes(bad[:-8])).to_bytes(8, "little")
        q.messages.clear()
        st, state = q.deserialize(bytes(bad))
        assert st == ERROR and not state.value
        assert "integrator = 3 is outside" in q.errors()[-1].text, q.log_text()

