"""The clock in air: closed forms for buoyancy, added mass and the rod's
expansion, the outside numbers they are held against, and a year of weather.

A bob of mass m and density rho_b displaces V = m / rho_b of air. Gravity
pulls (m - rho V) (buoyancy) while (m + m_a) moves, m_a the mass of the
entrained air (Nelson and Olsson, Am. J. Phys. 54, 112 (1986)): the
potential-flow part k rho V (k = 1/2 for a sphere, Landau and Lifshitz,
Fluid Mechanics, Sec. 11) and the viscous boundary layer's
c_bl rho V delta / R, delta = sqrt(2 mu / (rho omega0)) (c_bl = 9/4 for a
sphere, Stokes 1851). For a point bob on a rod of length L the equation is

    (m + m_a) L phi'' = -(m - rho V) g sin(phi) + ...

so every period scales with sqrt((m + m_a) / (m - rho V)) (``period_factor``)
and the rate (T0/T - 1) changes by its inverse. A length L (1 + alpha dT)
scales the period with sqrt(1 + alpha dT): -alpha/2 per kelvin in the rate
(Hoyng, Am. J. Phys. 82, 1053 (2014), Sec. VII: -delta_l / 2 l0).
"""

from __future__ import annotations

import math

import numpy as np

from .analytic import SECONDS_PER_DAY
PA_PER_HPA = 100.0
PA_PER_INHG = 3386.389  # one conventional inch of mercury (0 degC, standard gravity)

# Outside numbers (docs/air.md): Matthys, Accurate Clock Pendulums (2004),
# 0.2-0.4 s/day per inch of mercury (a loss when the pressure rises), and
# the Trinity College clock before its compensator, -8.6 ms/day per mbar.
MATTHYS_S_PER_DAY_PER_INHG = (0.2, 0.4)
TRINITY_S_PER_DAY_PER_HPA = -8.6e-3

# Expansion coefficients of the rod (1/K): typical handbook values for
# carbon steel and Invar 36.
ALPHA_STEEL = 11.5e-6
ALPHA_INVAR = 1.2e-6


def sphere_radius(mass: float, density: float) -> float:
    """Radius (m) of a sphere of this mass (kg) and density (kg/m^3)."""
    return (3.0 * mass / (4.0 * math.pi * density)) ** (1.0 / 3.0)


def added_mass(rho: float, mu: float, volume: float, k: float, radius: float,
               c_bl: float, omega0: float) -> float:
    """Mass (kg) of the entrained air: V (k rho + c_bl sqrt(2 mu rho / omega0) / R)."""
    m_a = rho * k
    if radius > 0:
        m_a += c_bl * math.sqrt(2.0 * mu * rho / omega0) / radius
    return m_a * volume


def period_factor(rho: float, mu: float, mass: float, bob_density: float, k: float = 0.5,
                  radius: float = 0.0, c_bl: float = 2.25, omega0: float = 1.0) -> float:
    """T(rho) / T(0) = sqrt((m + m_a) / (m - rho V)) for the bob in still air."""
    volume = mass / bob_density
    m_a = added_mass(rho, mu, volume, k, radius, c_bl, omega0)
    return math.sqrt((mass + m_a) / (mass - rho * volume))


def thermal_rate_coefficient(alpha: float) -> float:
    """The clock's rate change (s/day per K, positive: gains) from the rod's
    expansion alone: -alpha/2 x 86400, to first order."""
    return -0.5 * alpha * SECONDS_PER_DAY


def per_inhg_to_per_hpa(x: float) -> float:
    return x * PA_PER_HPA / PA_PER_INHG


def weather_year(days: float = 365.0, step_hours: float = 1.0, seed: int = 1,
                 pressure_hpa: float = 1013.25, temperature_c: float = 20.0,
                 seasonal_hpa: float = 3.0, seasonal_k: float = 4.0,
                 synoptic_hpa: float = 9.0, synoptic_k: float = 1.0) -> dict[str, np.ndarray]:
    """A smooth year of weather at a clock: time (s), pressure (Pa) and
    temperature (K), hourly.

    Pressure: a seasonal cosine (highest in late winter) plus a synoptic
    part, the sum of 24 cosines with periods from 2 to 20 days and random
    phases, scaled to `synoptic_hpa` rms; temperature likewise (the case's
    air lags the room: a smaller synoptic part, the seasonal cosine
    coldest in late January). The same seed gives the same year."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, days * SECONDS_PER_DAY + 0.5, step_hours * 3600.0)
    year = 365.25 * SECONDS_PER_DAY

    def synoptic(rms: float) -> np.ndarray:
        periods = np.geomspace(2.0, 20.0, 24) * SECONDS_PER_DAY
        phases = rng.uniform(0.0, 2.0 * math.pi, periods.size)
        weights = rng.uniform(0.5, 1.5, periods.size)
        s = (weights[:, None] * np.cos(2.0 * math.pi * t[None, :] / periods[:, None] + phases[:, None])).sum(axis=0)
        return s * rms / math.sqrt(0.5 * float((weights ** 2).sum()))

    p = pressure_hpa + seasonal_hpa * np.cos(2.0 * math.pi * (t - 45 * SECONDS_PER_DAY) / year) + synoptic(synoptic_hpa)
    temp = temperature_c - seasonal_k * np.cos(2.0 * math.pi * (t - 25 * SECONDS_PER_DAY) / year) + synoptic(synoptic_k)
    return {"time": t, "pressure": p * PA_PER_HPA, "temperature": temp + 273.15}
