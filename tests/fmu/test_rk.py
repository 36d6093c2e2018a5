"""The shared Dormand-Prince 5(4) integrator (src_c/runtime/cw_rk.c) alone,
through libcw_rk_probe.so (in CW_BUILD_DIR, default build/) and ctypes."""

from __future__ import annotations

import ctypes as C
import math
import random

import numpy as np
import pytest

from cwtest import BUILD_DIR

MAXN = 8  # CW_RK_MAXN
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
        ("k", Vec * 7),
        ("rcont", Vec * 5),
        ("n_accepted", C.c_long),
        ("n_rejected", C.c_long),
        ("n_rhs", C.c_long),
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
    return lib


class Problem:
    """A right-hand side that records the times it is evaluated at."""

    def __init__(self, n, f):
        self.n = n
        self.times: list[float] = []

        def rhs(ctx, t, x, dx):
            self.times.append(t)
            y = f(t, [x[i] for i in range(n)])
            for i in range(n):
                dx[i] = y[i]

        self.c = RHS(rhs)


def decay():
    return Problem(1, lambda t, x: [-x[0]])


def oscillator():
    return Problem(2, lambda t, x: [x[1], -x[0]])


def pendulum():
    return Problem(2, lambda t, x: [x[1], -9.81 * math.sin(x[0])])


def fixed_steps(lib, prob, x0, t_end, n_steps):
    x, out = Vec(*x0), Vec()
    h = t_end / n_steps
    for k in range(n_steps):
        lib.cw_rk_single_step(prob.n, prob.c, None, k * h, x, h, out)
        x[:] = out[:]
    return np.array(x[: prob.n])


def advance(lib, prob, x0, t_start, t_end, rtol, atol, h_max=0.0, rk=None, h_next=0.0,
            observer=None, max_steps=None):
    rk = rk or Rk()
    lib.cw_rk_init(C.byref(rk), prob.n, rtol, atol, h_max)
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


def _one_step(lib, prob, x0, h):
    """Exactly one accepted step [0, h] (tolerances that accept anything)."""
    res, t, x1, _, rk = advance(lib, prob, x0, 0.0, h, 1e6, 1e6, h_next=h)
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
