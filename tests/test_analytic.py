"""Closed forms of Ziemkiewicz (Z) and Hoyng (H) against each other and the papers' numbers."""

import math

import numpy as np
import pytest
from scipy import integrate

from clockwork.physics import analytic as an

DEG = math.pi / 180.0


def test_agm_known_value():
    # AGM(1, sqrt 2) = 1.19814023473559220744 (Gauss's constant 1/G)
    assert an.agm(1.0, math.sqrt(2.0)) == pytest.approx(1.19814023473559220744, rel=1e-15)
    assert an.agm(1.0, 1.0) == 1.0


@pytest.mark.parametrize("deg", [0.5, 5.0, 30.0, 120.0, 170.0])
def test_exact_period_agrees_with_plain_agm_and_long_series(deg):
    A = deg * DEG
    T0 = an.small_angle_period(1.0, 9.81)
    plain = T0 / an.agm(1.0, math.cos(A / 2))
    assert an.exact_period(A, 1.0, 9.81) == pytest.approx(plain, rel=1e-14)
    if deg <= 120.0:  # the series converges like sin(A/2)^(2n)
        assert an.series_period(A, 1.0, 9.81, terms=200) == pytest.approx(plain, rel=1e-14)
    assert an.circular_error(A) == pytest.approx(plain / T0 - 1.0, rel=1e-12, abs=1e-16)


def test_circular_error_small_angles():
    # E_C = A^2/16 + 11 A^4/3072 + O(A^6)
    for A in (1e-4, 1e-2, 1.0 * DEG):
        expected = A**2 / 16 + 11 * A**4 / 3072
        assert an.circular_error(A) == pytest.approx(expected, rel=1e-6)
    # Z Sec. II: A = 2 deg gives E_C ~ 7e-5, ~6 s/day
    assert an.circular_error(2 * DEG) == pytest.approx(7.616e-5, rel=1e-3)
    assert 6.0 < an.to_s_per_day(an.circular_error(2 * DEG)) < 7.0


def test_series_truncation_error_is_the_next_term():
    """Z Eq. (2) truncated after 1 or 2 corrections misses about the next term."""
    A = 5 * DEG
    k2 = math.sin(A / 2) ** 2
    T0 = an.small_angle_period(1.0, 9.81)
    exact = an.exact_period(A, 1.0, 9.81)
    miss1 = (exact - an.series_period(A, 1.0, 9.81, 1)) / T0
    miss2 = (exact - an.series_period(A, 1.0, 9.81, 2)) / T0
    assert miss1 == pytest.approx((3 / 8) ** 2 * k2**2, rel=0.01)
    assert miss2 == pytest.approx((15 / 48) ** 2 * k2**3, rel=0.01)
    # 5.1e-7 = 16 s/year (Z App. A says "under 6 s/year" for one term at 5 deg)
    assert miss1 == pytest.approx(5.09e-7, rel=0.01)


def test_B7_paper_number():
    ee = an.escapement_error_B7(5 * DEG, 2 * DEG, 1000.0)
    assert ee == pytest.approx(-1.178e-3, rel=1e-3)
    assert an.to_s_per_day(ee) == pytest.approx(-101.8, abs=0.05)
    assert an.escapement_error_B7(2 * DEG, 2 * DEG, 1000.0) == 0.0


@pytest.mark.parametrize("L", [1.0, 0.25, 2.0])
def test_B6_energy_balance_for_any_length(L):
    A, phi_r, Q, m, g = 5 * DEG, 2 * DEG, 1000.0, 1.3, 9.81
    M = an.grasshopper_torque_for_amplitude(A, phi_r, Q, m, L, g)
    energy = 0.5 * m * L**2 * (g / L) * A**2
    assert 4 * M * phi_r == pytest.approx(2 * math.pi * energy / Q, rel=1e-14)
    if L == 1.0:  # the paper's form pi m omega^2 A^2 / (4 Q alpha_r)
        assert M == pytest.approx(math.pi * m * g * A**2 / (4 * Q * phi_r), rel=1e-14)


def test_epsilon_Q_and_s_per_day():
    assert an.epsilon_from_Q(1000.0) == 5e-4
    assert an.Q_from_epsilon(an.epsilon_from_Q(1234.5)) == pytest.approx(1234.5, rel=1e-15)
    assert an.to_s_per_day(1e-5) == pytest.approx(0.864)
    np.testing.assert_allclose(an.to_s_per_day([1e-5, -2e-5]), [0.864, -1.728])


def test_hoyng_circular_bessel_expansion():
    lam = np.array([0.0, 0.01, 0.05, 0.1])
    series = -(lam**2) / 16 + lam**4 / 384
    np.testing.assert_allclose(an.hoyng_circular(lam), series, rtol=1e-5, atol=1e-18)
    np.testing.assert_allclose(an.hoyng_circular(lam, bessel=False), -(lam**2) / 16)


@pytest.mark.parametrize("mu,eps", [(2e-5, 2.5e-4), (4e-5, 2.5e-4), (1e-5, 5e-5), (1.5e-5, 1.167245e-4)])
def test_hoyng_eq19_20_are_eq15_16_at_stationarity(mu, eps):
    phi0 = 0.03
    lam = an.hoyng_stationary_amplitude(mu, eps, phi0)
    assert -2 * eps * lam**2 + 4 * mu * phi0 / math.pi == pytest.approx(0.0, abs=1e-20)  # Eq. (15)
    assert an.hoyng_stationary_rate(mu, eps, phi0) == pytest.approx(
        an.hoyng_rate(lam, mu, phi0), rel=1e-12, abs=1e-18)


def test_hoyng_paper_numbers():
    eps, phi0, mu0, mu1 = 2.5e-4, 0.03, 2e-5, 4e-5
    # Point A gains ~1.1e-4 (~10 s/day); 3.2e-4 right after the jump; ~2e-4 (~17 s/day) at B.
    rate_a = an.hoyng_stationary_rate(mu0, eps, phi0)
    assert rate_a == pytest.approx(1.1e-4, rel=0.05)
    lam_a = an.hoyng_stationary_amplitude(mu0, eps, phi0)
    assert an.hoyng_rate(lam_a, mu1, phi0) == pytest.approx(3.2e-4, rel=0.01)
    rate_b = an.hoyng_stationary_rate(mu1, eps, phi0)
    assert an.to_s_per_day(rate_b) == pytest.approx(17.0, abs=0.5)
    # Point C (mu0 = 1.5e-5, eps = 1.167245e-4) runs at nominal rate by construction.
    assert abs(an.hoyng_stationary_rate(1.5e-5, 1.167245e-4, phi0)) < 1e-9
    # Fig. 3: minimum torque keeps lambda = phi0, with no escapement error left.
    mu_min = an.hoyng_min_torque(eps, phi0)
    assert an.hoyng_stationary_amplitude(mu_min, eps, phi0) == pytest.approx(phi0, rel=1e-14)
    assert an.hoyng_stationary_rate(mu_min, eps, phi0) == pytest.approx(
        -mu_min * phi0 / (8 * math.pi * eps), rel=1e-6)
    assert math.isnan(an.hoyng_stationary_rate(0.9 * mu_min, eps, phi0))


def test_hoyng_amplitude_after_jump():
    eps, phi0, mu0, mu1 = 2.5e-4, 0.03, 2e-5, 4e-5
    lam = an.hoyng_amplitude_after_jump(np.array([-5.0, 0.0, 1e6]), mu0, mu1, eps, phi0)
    assert lam[0] == pytest.approx(an.hoyng_stationary_amplitude(mu0, eps, phi0), rel=1e-14)
    assert lam[1] == pytest.approx(lam[0], rel=1e-14)
    assert lam[2] == pytest.approx(an.hoyng_stationary_amplitude(mu1, eps, phi0), rel=1e-14)


def test_hoyng_phase_shift():
    eps, phi0, mu0, mu1 = 2.5e-4, 0.03, 2e-5, 4e-5
    dpsi = an.hoyng_phase_shift(mu0, mu1, eps, phi0)
    assert round(dpsi, 3) == 0.295  # H Sec. V
    # Independent check: the same integral in t, without the substitution.
    rate_b = an.hoyng_stationary_rate(mu1, eps, phi0)

    def excess(t):
        return an.hoyng_rate(an.hoyng_amplitude_after_jump(t, mu0, mu1, eps, phi0), mu1, phi0) - rate_b

    direct = sum(integrate.quad(excess, a, b, epsabs=0, epsrel=1e-12, limit=200)[0]
                 for a, b in [(0, 2e3), (2e3, 1e4), (1e4, 1e5)])
    assert direct == pytest.approx(dpsi, rel=1e-8)
    # ~0.1 s for a 1 m pendulum (period 2 s)
    assert dpsi / (2 * math.pi) * 2.0 == pytest.approx(0.094, abs=0.001)


def test_single_impulse_C6():
    e, eps = 1e-5, 1e-4
    lam = math.sqrt(e / (2 * math.pi * eps))  # stationary C4
    for phi1 in (-0.01, 0.0, 0.005, 0.02):
        tan_psi1 = phi1 / math.sqrt(lam**2 - phi1**2)
        c5 = -(lam**2) / 16 - e / (2 * math.pi * lam**2) * tan_psi1
        assert an.single_impulse_stationary_rate(e, eps, phi1) == pytest.approx(c5, rel=1e-13)
    nominal = an.single_impulse_stationary_rate(e, eps, 0.0)
    assert nominal == pytest.approx(-(lam**2) / 16, rel=1e-14)
    # Impulse after the zero slows the clock, before it speeds it up.
    assert an.single_impulse_stationary_rate(e, eps, 0.01) < nominal
    assert an.single_impulse_stationary_rate(e, eps, -0.01) > nominal
