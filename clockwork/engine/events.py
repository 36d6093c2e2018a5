"""Event location: the Illinois variant of regula falsi on a step length.

The master brackets an indicator's sign change between a step length ``lo``
(no sign change) and ``hi`` (sign changed). Each trial step is a rollback
and a shorter co-simulation step; Illinois halves the weight of an end
point that is kept twice in a row, which turns regula falsi's linear
convergence superlinear without losing the bracket.
"""

from __future__ import annotations


def crossed(z0: float, z1: float) -> bool:
    """An indicator crossed zero: from a non-zero value to zero or the other
    sign (src_c/master/cw_numerics.h has the twin)."""
    return (z0 > 0.0 and z1 <= 0.0) or (z0 < 0.0 and z1 >= 0.0)


def earliest(crossing: list[bool], z0, z1) -> int:
    """The crossing indicator whose linear interpolant crosses first (the
    first of equals), or -1 when none crossed."""
    lead, best = -1, 0.0
    for k, c in enumerate(crossing):
        if c:
            x = z0[k] / (z0[k] - z1[k])
            if lead < 0 or x < best:
                lead, best = k, x
    return lead


def input_polynomial(u0: float, d1: float, d2: float, dt: float) -> float:
    """An input's value dt s after it was set with value u0 and time
    derivatives d1, d2 (src_c/master/cw_polynomial.h has the twin, in this
    order of operations)."""
    return u0 + dt * (d1 + 0.5 * dt * d2)


class Illinois:
    def __init__(self, lo: float, z_lo: float, hi: float, z_hi: float):
        self.lo, self.z_lo = lo, z_lo
        self.hi, self.z_hi = hi, z_hi
        self._kept = 0  # +1: lo kept last time, -1: hi kept last time
        self.iterations = 0

    def next(self) -> float:
        """Next trial: where the secant through the bracket crosses zero."""
        dz = self.z_lo - self.z_hi
        if dz == 0.0:
            return 0.5 * (self.lo + self.hi)
        return (self.z_lo * self.hi - self.z_hi * self.lo) / dz

    def update(self, x: float, z: float, crossed: bool) -> None:
        self.iterations += 1
        if crossed:
            self.hi, self.z_hi = x, z
            if self._kept == 1:
                self.z_lo *= 0.5
            self._kept = 1
        else:
            self.lo, self.z_lo = x, z
            if self._kept == -1:
                self.z_hi *= 0.5
            self._kept = -1


def _hermite_coefficients(h: float, z0: float, dz0: float, z1: float, dz1: float):
    """p(s) = a s^3 + b s^2 + c s + d on s in [0, 1] (s = x/h)."""
    c = h * dz0
    d = z0
    a = 2 * z0 - 2 * z1 + h * dz0 + h * dz1
    b = -3 * z0 + 3 * z1 - 2 * h * dz0 - h * dz1
    return a, b, c, d


def _quintic_coefficients(h: float, z0: float, dz0: float, ddz0: float, z1: float, dz1: float, ddz1: float):
    """p(s) = sum c[k] s^k on s in [0, 1] (s = x/h) matching z, dz/dt and d2z/dt2 at both ends."""
    c0, c1, c2 = z0, h * dz0, 0.5 * h * h * ddz0
    a = z1 - (c0 + c1 + c2)
    b = h * dz1 - (c1 + 2.0 * c2)
    c = h * h * ddz1 - 2.0 * c2
    return [c0, c1, c2, 10.0 * a - 4.0 * b + 0.5 * c, -15.0 * a + 7.0 * b - c, 6.0 * a - 3.0 * b + 0.5 * c]


def hermite_root(h: float, z0: float, dz0: float, z1: float, dz1: float,
                 ddz0: float | None = None, ddz1: float | None = None) -> float | None:
    """Root in (0, h) of the Hermite interpolant of the indicator over the step.

    The first guess of an event search, with the indicator's derivatives
    taken from the connected outputs' derivatives: the cubic through (z,
    dz/dt) at both ends is accurate to O(h^4); given d2z/dt2 at both ends
    too, the quintic is accurate to O(h^6). Newton's method on the
    polynomial, kept inside the bracket by bisection.
    """
    if not (z0 * z1 < 0.0 or z1 == 0.0):
        return None
    if ddz0 is not None and ddz1 is not None:
        coef = _quintic_coefficients(h, z0, dz0, ddz0, z1, dz1, ddz1)
    else:
        a, b, c, d = _hermite_coefficients(h, z0, dz0, z1, dz1)
        coef = [d, c, b, a]
    x = _newton_in_bracket(coef, z0 / (z0 - z1) if z0 != z1 else 0.5, 0.0, 1.0, z0 > 0.0, False)
    return x * h if 0.0 < x < 1.0 else None


def _newton_in_bracket(coef: list[float], x: float, lo: float, hi: float, positive: bool,
                       relative: bool) -> float:
    """A root of the polynomial in (lo, hi), where it is `positive` at lo:
    Newton's method from x, kept inside the shrinking bracket by bisection,
    until a step is below 1e-15 (relative: <= 1e-15 hi)."""
    slope = [k * ck for k, ck in enumerate(coef)][1:]
    for _ in range(50):
        f = _horner(coef, x)
        if f == 0.0:
            break
        if (f > 0.0) == positive:
            lo = x
        else:
            hi = x
        df = _horner(slope, x)
        x_new = x - f / df if df != 0.0 else 0.5 * (lo + hi)
        if not lo < x_new < hi:
            x_new = 0.5 * (lo + hi)
        if (abs(x_new - x) <= 1e-15 * hi) if relative else (abs(x_new - x) < 1e-15):
            return x_new
        x = x_new
    return x


def _horner(coef: list[float], x: float) -> float:
    value = 0.0
    for ck in reversed(coef):
        value = value * x + ck
    return value


def hermite_extremum(h: float, z0: float, dz0: float, z1: float, dz1: float) -> float | None:
    """Where in (0, h) the Hermite interpolant reaches the other sign, if it does.

    Returns the location of the interpolant's extremum when z0 and z1 have
    the same sign but the extremum between them has the opposite sign: the
    mark of two crossings hidden inside one step.
    """
    a, b, c, d = _hermite_coefficients(h, z0, dz0, z1, dz1)
    # p'(s) = 3a s^2 + 2b s + c
    roots = []
    if abs(a) < 1e-300:
        if b != 0:
            roots = [-c / (2 * b)]
    else:
        disc = b * b - 3 * a * c
        if disc >= 0:
            r = disc ** 0.5
            roots = [(-b - r) / (3 * a), (-b + r) / (3 * a)]
    for sx in sorted(roots):
        if 0.0 < sx < 1.0:
            val = ((a * sx + b) * sx + c) * sx + d
            if (val > 0) != (z0 > 0) or val == 0.0:
                return sx * h
    return None


# -- prediction: where an indicator will cross, before the step ----------------

PREDICTION_HORIZON = 16.0  # extrapolate at most this many times the last step's length
_SCAN = 8  # points at which the extrapolant is scanned for its first sign change


def extrapolants(h: float, z0: float, dz0: float, z1: float, dz1: float,
                 ddz0: float | None = None, ddz1: float | None = None) -> tuple[list[float], list[float]]:
    """The Hermite polynomials through the last step, continued past its end.

    The last step of h s ran from a (z0, dz/dt, d2z/dt2) to b (z1, ...).
    Returns the coefficients, in y = (time since b) / h, of a higher and a
    lower order polynomial matching those data: quintic and quartic (b's
    second derivative only) when both second derivatives are given, else
    cubic and quadratic (a's slope left out). Their roots ahead of b differ
    by about the lower one's error, which is the error estimate.
    """
    c1 = h * dz1
    if ddz0 is not None and ddz1 is not None:
        hh = h * h
        c2 = 0.5 * hh * ddz1
        # What the Taylor terms at b leave of a's value, slope and curvature.
        e0 = z0 - ((z1 - c1) + c2)
        e1 = h * dz0 - (c1 - hh * ddz1)
        e2 = hh * ddz0 - hh * ddz1
        high = [z1, c1, c2, -0.5 * (e2 + 8.0 * e1 + 20.0 * e0), -(e2 + 7.0 * e1 + 15.0 * e0),
                -0.5 * (e2 + 6.0 * e1 + 12.0 * e0)]
        low = [z1, c1, c2, -(4.0 * e0 + e1), -(3.0 * e0 + e1)]
    else:
        e0 = z0 - (z1 - c1)
        e1 = h * dz0 - c1
        high = [z1, c1, 3.0 * e0 + e1, 2.0 * e0 + e1]
        low = [z1, c1, e0]
    return high, low


def first_root(coef: list[float], y_max: float) -> float | None:
    """The first y in (0, y_max] where the polynomial changes sign from its
    value at 0 (found on a scan of _SCAN points, then by Newton's method
    kept inside the bracket), or None."""
    z0 = coef[0]
    positive = z0 > 0.0
    lo, f_lo = 0.0, z0
    hi = f_hi = None
    for i in range(1, _SCAN + 1):
        y = y_max * i / _SCAN
        f = _horner(coef, y)
        if f == 0.0 or (f > 0.0) != positive:
            hi, f_hi = y, f
            break
        lo, f_lo = y, f
    if hi is None:
        return None
    if f_hi == 0.0:
        return hi
    return _newton_in_bracket(coef, lo + (hi - lo) * (f_lo / (f_lo - f_hi)), lo, hi, positive, True)


def slope_at(coef: list[float], y: float) -> float:
    """d/dy of the polynomial at y."""
    return _horner([k * ck for k, ck in enumerate(coef)][1:], y)
