"""Events found in a sampled result: ticks and escapement switches.

Ticks are upward zero crossings of phi, placed by cubic Hermite
interpolation between the two samples around them (phi and its derivative
w), or linearly without w.

An escapement switch shows twice in a result: the torque output changes
sign between two rows (the bracket), and the pendulum's velocity w gets a
kink where the new torque reached the pendulum (its slope jumps by
Delta tau / I). The bracket alone only knows the switch to a row; the kink
places it between rows: w around the bracket is fitted by least squares
with a polynomial plus a ramp max(t - t_s, 0) and the t_s of the smallest
residual is the switch time. On a result sampled every 0.01 s it finds a
kink to ~1e-8 s (tests/test_kit.py), to ~1e-6 s on co-simulated results
(whose w has small kinks at every communication step) and ~1e-4 s where a
fast mechanism vibration rides on w; a master that switches at its next
communication point shows its kink there. A row off the output grid with
the new torque (a master that wrote a row at its located event) gives the
switch time directly.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq, minimize_scalar

SIDE = 10  # samples each side of a bracket used for the kink fit
DEGREE = 7


def ticks(t: np.ndarray, phi: np.ndarray, w: np.ndarray | None = None) -> np.ndarray:
    out = []
    idx = np.nonzero((phi[:-1] < 0.0) & (phi[1:] >= 0.0))[0]
    for i in idx:
        t0, t1 = t[i], t[i + 1]
        h = t1 - t0
        if h <= 0.0:
            out.append(t1)
            continue
        p0, p1 = phi[i], phi[i + 1]
        if w is None:
            out.append(t0 - p0 * h / (p1 - p0))
            continue
        m0, m1 = w[i] * h, w[i + 1] * h

        def f(s):
            h00 = 2 * s**3 - 3 * s**2 + 1
            h10 = s**3 - 2 * s**2 + s
            h01 = -2 * s**3 + 3 * s**2
            h11 = s**3 - s**2
            return h00 * p0 + h10 * m0 + h01 * p1 + h11 * m1

        if p1 == 0.0:
            out.append(t1)
            continue
        try:
            s = brentq(f, 0.0, 1.0, xtol=1e-15)
        except ValueError:  # the Hermite cubic does not change sign: fall back to the chord
            s = -p0 / (p1 - p0)
        out.append(t0 + s * h)
    return np.array(out)


def brackets(t: np.ndarray, signal: np.ndarray) -> list[tuple[int, int]]:
    """(i, j): the last row with the old sign and the first with the new one."""
    s = np.sign(signal)
    idx = np.nonzero(s[1:] != s[:-1])[0]
    return [(int(i), int(i) + 1) for i in idx]


def _unique(t, y):
    keep = np.concatenate(([True], np.diff(t) > 0))
    return t[keep], y[keep]


def kink(t: np.ndarray, w: np.ndarray, lo: float, hi: float) -> float | None:
    """Time of the slope jump of w in [lo, hi] (samples t, w around it), or None."""
    t, w = _unique(np.asarray(t, float), np.asarray(w, float))
    if len(t) < 6:
        return None
    tc = 0.5 * (t[0] + t[-1])
    sc = 0.5 * (t[-1] - t[0]) or 1.0
    s = (t - tc) / sc
    deg = min(DEGREE, len(t) - 6)
    if deg < 2:
        return None
    base = np.vander(s, deg + 1)
    wn = w / (np.max(np.abs(w)) or 1.0)

    def residual(ts):
        x = np.maximum(s - (ts - tc) / sc, 0.0)
        a = np.column_stack([base, x, x * x, x * x * x])
        coef, res, rank, _ = np.linalg.lstsq(a, wn, rcond=None)
        r = a @ coef - wn
        return float(r @ r)

    grid = np.linspace(lo, hi, 81)
    vals = [residual(x) for x in grid]
    k = int(np.argmin(vals))
    a, b = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
    if b <= a:
        return float(grid[k])
    r = minimize_scalar(residual, bounds=(a, b), method="bounded", options={"xatol": 1e-12 * sc})
    cands = [(vals[k], grid[k]), (r.fun, r.x)]
    # A kink on a row (a master that switched at a communication point, or
    # wrote a row at the located event) is a corner of the residual: try the rows.
    cands += [(residual(x), x) for x in t[(t >= lo) & (t <= hi)]]
    return float(min(cands)[1])


def switches(t: np.ndarray, signal: np.ndarray, w: np.ndarray | None,
             grid: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Switch times and the brackets' widths (s).

    A switch is the time of the first row with the new sign when that row
    lies off the output `grid` (the tool wrote a row at its event, or steps
    off the grid and switched there), else the kink of w around the bracket."""
    br = brackets(t, signal)
    times, widths = [], []
    for n, (i, j) in enumerate(br):
        widths.append(t[j] - t[i])
        if grid is not None and abs(t[j] - round(t[j] / grid) * grid) > 1e-6 * grid:
            times.append(t[j])
            continue
        if w is None:
            times.append(0.5 * (t[i] + t[j]))
            continue
        # The kink lies after the last row with the old torque and at most two
        # rows after the first with the new one (a tool that passes outputs on
        # after the step feeds the pendulum a step late).
        lo_i = max(i - SIDE + 1, 0)
        hi_i = min(j + SIDE + 1, len(t) - 1)
        if n > 0:
            lo_i = max(lo_i, (br[n - 1][1] + i) // 2 + 1)
        if n + 1 < len(br):
            hi_i = min(hi_i, (j + br[n + 1][0]) // 2)
        lo, hi = t[i], t[min(j + 2, hi_i)]
        tk = kink(t[lo_i:hi_i + 1], w[lo_i:hi_i + 1], lo, hi) if hi > lo else None
        times.append(tk if tk is not None else 0.5 * (t[i] + t[j]))
    return np.array(times), np.array(widths)


def match(found: np.ndarray, expected: np.ndarray, t_lo: float, t_hi: float) -> dict:
    """Pair expected events in [t_lo, t_hi] with the nearest found ones."""
    exp = expected[(expected >= t_lo) & (expected <= t_hi)]
    got = found[(found >= t_lo - 0.5) & (found <= t_hi + 0.5)] if len(found) else found
    if len(exp) == 0:
        return {"expected": 0, "found": int(len(got)), "worst_s": 0.0, "missing": 0, "extra": int(len(got))}
    if len(got) == 0:
        return {"expected": int(len(exp)), "found": 0, "worst_s": float("inf"), "missing": int(len(exp)), "extra": 0}
    k = np.clip(np.searchsorted(got, exp), 1, len(got) - 1) if len(got) > 1 else np.zeros(len(exp), int)
    if len(got) > 1:
        left, right = got[k - 1], got[k]
        nearest = np.where(np.abs(exp - left) <= np.abs(exp - right), left, right)
    else:
        nearest = np.full(len(exp), got[0])
    err = np.abs(nearest - exp)
    used = set(nearest.tolist())
    inner = got[(got >= t_lo) & (got <= t_hi)]
    # extra: found inside the window and nearest to no expected event
    extra = sum(1 for x in inner.tolist() if x not in used)
    return {"expected": int(len(exp)), "found": int(len(inner)), "worst_s": float(err.max()),
            "worst_at_s": float(exp[int(err.argmax())]),
            "missing": int(len(exp) - len(used)), "extra": int(extra)}
