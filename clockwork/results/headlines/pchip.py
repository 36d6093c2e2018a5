"""Monotone piecewise cubic interpolation (PCHIP: Fritsch and Carlson's
shape-preserving slopes as weighted harmonic means, Moler's one-sided
end slopes), in numpy alone.

The headlines interpolate sweep curves at a handful of points; importing
scipy.interpolate for that would cost a run about a third of a second of
start-up. tests/test_results.py holds this against
scipy.interpolate.PchipInterpolator.
"""

from __future__ import annotations

import numpy as np


def _end_slope(h_near: float, h_far: float, m_near: float, m_far: float) -> float:
    """One-sided three-point slope at an end, kept from overshooting."""
    d = ((2.0 * h_near + h_far) * m_near - h_near * m_far) / (h_near + h_far)
    if np.sign(d) != np.sign(m_near):
        return 0.0
    if np.sign(m_near) != np.sign(m_far) and abs(d) > 3.0 * abs(m_near):
        return 3.0 * m_near
    return d


def slopes(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """dy/dx at the nodes: zero at a local extremum or beside a flat piece,
    else the weighted harmonic mean of the neighbouring secants."""
    h = np.diff(x)
    m = np.diff(y) / h
    if len(x) == 2:
        return np.array([m[0], m[0]])
    d = np.zeros_like(y, dtype=float)
    left, right = m[:-1], m[1:]
    smooth = (np.sign(left) == np.sign(right)) & (left != 0.0) & (right != 0.0)
    w_left = h[1:] + 2.0 * h[:-1]
    w_right = 2.0 * h[1:] + h[:-1]
    with np.errstate(divide="ignore", invalid="ignore"):
        inverse = (w_right / left + w_left / right) / (w_left + w_right)
    d[1:-1] = np.where(smooth, 1.0 / np.where(smooth, inverse, 1.0), 0.0)
    d[0] = _end_slope(h[0], h[1], m[0], m[1])
    d[-1] = _end_slope(h[-1], h[-2], m[-1], m[-2])
    return d


def pchip(x, y, at):
    """The PCHIP interpolant through (x, y) (x strictly increasing) at `at`;
    points outside [x[0], x[-1]] continue the end pieces."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    d = slopes(x, y)
    at_arr = np.asarray(at, dtype=float)
    k = np.clip(np.searchsorted(x, at_arr, side="right") - 1, 0, len(x) - 2)
    h = x[k + 1] - x[k]
    secant = (y[k + 1] - y[k]) / h
    # The cubic on each piece in powers of s = at - x[k].
    c3 = (d[k] + d[k + 1] - 2.0 * secant) / h
    c2 = (secant - d[k]) / h - c3
    c3 = c3 / h
    s = at_arr - x[k]
    value = ((c3 * s + c2) * s + d[k]) * s + y[k]
    return float(value) if np.ndim(at) == 0 else value
