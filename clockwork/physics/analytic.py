"""Closed-form results of the two papers.

Z = Ziemkiewicz, Phys. Rev. E 103, 062208 (2021); H = Hoyng, Am. J. Phys. 82,
1053 (2014). SI units unless stated, angles in rad. Relative errors are
dimensionless; Ziemkiewicz's E = T'/T - 1 is positive for a slow clock,
Hoyng's rate psi-dot - 1 is positive for a fast one.

Hoyng's functions use his normalized pendulum: omega0 = 1 (time in units of
1/omega0), friction eps (phi'' + 2 eps phi' + sin phi = m), torque mu in units
of m g L, switch angle phi0 (= Ziemkiewicz's alpha_r).
"""

import math

import numpy as np

SECONDS_PER_DAY = 86400.0


def to_s_per_day(rel):
    """Relative rate or period error -> seconds per day."""
    return (np.asarray(rel, dtype=float) * SECONDS_PER_DAY)[()]


# --- circular error -------------------------------------------------------


def small_angle_period(L, g):
    """T0 = 2 pi sqrt(L/g) in s."""
    return 2.0 * math.pi * math.sqrt(L / g)


def agm(a, b):
    """Arithmetic-geometric mean of two positive numbers."""
    a, b = float(a), float(b)
    for _ in range(64):
        if abs(a - b) <= 1e-16 * a:
            break
        a, b = 0.5 * (a + b), math.sqrt(a * b)
    return 0.5 * (a + b)


def _agm_deficit(amplitude):
    """1 - AGM(1, cos(A/2)), computed without cancellation at small A.

    With a = 1 - u, b = 1 - v the AGM step reads u' = (u + v)/2,
    v' = 1 - sqrt(1 - u - v + u v); both stay accurate when u, v << 1.
    """
    u = 0.0
    v = 2.0 * math.sin(0.25 * amplitude) ** 2  # 1 - cos(A/2)
    for _ in range(64):
        if abs(u - v) <= 4e-16 * max(u, v):
            break
        u, v = 0.5 * (u + v), -math.expm1(0.5 * math.log1p(-(u + v - u * v)))
    return 0.5 * (u + v)


def exact_period(amplitude, L, g):
    """Period of the free pendulum, T0 / AGM(1, cos(A/2)), in s."""
    return small_angle_period(L, g) / (1.0 - _agm_deficit(amplitude))


def circular_error(amplitude):
    """E_C = T(A)/T0 - 1 from the AGM (Z Sec. II)."""
    d = _agm_deficit(amplitude)
    return d / (1.0 - d)


def series_period(amplitude, L, g, terms=1):
    """Z Eq. (2): T0 [1 + (1/2)^2 k^2 + (3/8)^2 k^4 + ...], k = sin(A/2).

    `terms` counts the correction terms after the leading 1.
    """
    k2 = math.sin(0.5 * amplitude) ** 2
    total, coef = 1.0, 1.0
    for n in range(1, terms + 1):
        coef *= (2 * n - 1) / (2 * n)
        total += coef**2 * k2**n
    return small_angle_period(L, g) * total


# --- Ziemkiewicz App. B (grasshopper) ---------------------------------------


def grasshopper_torque_for_amplitude(A, phi_r, Q, m, L, g):
    """Z Eq. (B6): torque (N.m) that sustains amplitude A.

    The escapement delivers 4 M phi_r per period (B3); the damping removes
    2 pi E / Q (Eq. 3) with E = m L^2 omega0^2 A^2 / 2 = m g L A^2 / 2. The
    paper writes E = m omega^2 A^2 / 2, i.e. L = 1 m; for general L
    M = pi m L^2 omega0^2 A^2 / (4 Q phi_r) = pi m g L A^2 / (4 Q phi_r).
    """
    return math.pi * m * g * L * A**2 / (4.0 * Q * phi_r)


def escapement_error_B7(A, phi_r, Q):
    """Z Eq. (B7): E_E = -pi (A - phi_r) / (4 Q phi_r), an estimate."""
    return -math.pi * (A - phi_r) / (4.0 * Q * phi_r)


# --- Hoyng (normalized units) ------------------------------------------------


def epsilon_from_Q(Q):
    """Hoyng's friction eps = 1/(2Q) (2 eps phi' == (omega0/Q) phi')."""
    return 1.0 / (2.0 * Q)


def Q_from_epsilon(eps):
    return 1.0 / (2.0 * eps)


def hoyng_circular(lam, bessel=True):
    """Circular-error term of the rate, H Eq. (A1): J1(lam)/lam - 1/2, or -lam^2/16."""
    lam = np.asarray(lam, dtype=float)
    if not bessel:
        out = -(lam**2) / 16.0
    else:
        from scipy import special  # start-up: most runs never need a Bessel function

        safe = np.where(lam == 0.0, 1.0, lam)
        out = np.where(lam == 0.0, 0.0, special.j1(safe) / safe - 0.5)
    return out[()]


def hoyng_min_torque(eps, phi0):
    """Smallest mu that keeps lambda above phi0 (H Sec. IV): pi eps phi0 / 2."""
    return 0.5 * math.pi * eps * phi0


def hoyng_stationary_amplitude(mu, eps, phi0):
    """H Eq. (19): lambda = phi0 sqrt(2 mu / (pi eps phi0))."""
    return phi0 * math.sqrt(2.0 * mu / (math.pi * eps * phi0))


def hoyng_stationary_rate(mu, eps, phi0):
    """H Eq. (20): stationary psi-dot - 1; nan when the pendulum stalls."""
    x = 2.0 * mu / (math.pi * eps * phi0) - 1.0
    if x < 0.0:
        return math.nan
    return -mu * phi0 / (8.0 * math.pi * eps) + eps * math.sqrt(x)


def hoyng_rate(lam, mu, phi0, bessel=False):
    """H Eq. (16): psi-dot - 1 = circ(lam) + (2 mu / (pi lam)) cos(psi0),
    cos(psi0) = sqrt(1 - (phi0/lam)^2); nan for lam < phi0."""
    lam = np.asarray(lam, dtype=float)
    c2 = 1.0 - (phi0 / lam) ** 2
    cos_psi0 = np.sqrt(np.where(c2 >= 0.0, c2, np.nan))
    return (hoyng_circular(lam, bessel) + 2.0 * mu / (math.pi * lam) * cos_psi0)[()]


def hoyng_amplitude_after_jump(t, mu0, mu1, eps, phi0):
    """H Eq. (18): lambda(t) for a torque jump mu0 -> mu1 at t = 0."""
    t = np.asarray(t, dtype=float)
    mu = np.where(t < 0.0, mu0, mu1 - (mu1 - mu0) * np.exp(-2.0 * eps * np.maximum(t, 0.0)))
    return np.sqrt(2.0 * phi0 / (math.pi * eps) * mu)[()]


def hoyng_phase_shift(mu0, mu1, eps, phi0):
    """Phase gained after a torque jump (H Sec. V), in rad:
    integral_0^inf (psi-dot(t) - psi-dot_B) dt with psi-dot from Eq. (16),
    lambda(t) from Eq. (18) and psi-dot_B the stationary rate at mu1.

    Substituting u = exp(-2 eps t) maps the tail onto [0, 1].
    """
    rate_b = hoyng_rate(hoyng_stationary_amplitude(mu1, eps, phi0), mu1, phi0)

    def integrand(u):
        if u == 0.0:
            return 0.0
        lam = math.sqrt(2.0 * phi0 / (math.pi * eps) * (mu1 - (mu1 - mu0) * u))
        return (hoyng_rate(lam, mu1, phi0) - rate_b) / (2.0 * eps * u)

    from scipy import integrate  # start-up: only the torque-jump headline needs it

    value, _ = integrate.quad(integrand, 0.0, 1.0, epsabs=0.0, epsrel=1e-12, limit=200)
    return value


def single_impulse_stationary_rate(e, eps, phi1):
    """H Eq. (C6): psi-dot - 1 for one impulse of energy e (units of m g L)
    per period at angle phi1: -e/(32 pi eps) - eps tan(psi1), with
    lambda = sqrt(e/(2 pi eps)) and tan(psi1) = phi1/sqrt(lambda^2 - phi1^2)."""
    lam2 = e / (2.0 * math.pi * eps)
    tan_psi1 = phi1 / math.sqrt(lam2 - phi1**2)
    return -e / (32.0 * math.pi * eps) - eps * tan_psi1
