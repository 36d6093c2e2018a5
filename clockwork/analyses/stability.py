"""How stable a clock is, as timekeepers measure it: the overlapping Allan
deviation and the time deviation of its ticks, with confidence intervals.

The ticks t_0 < t_1 < ... < t_N (s) are the clock's readings; its time
error against an ideal clock of the mean period T = (t_N - t_0)/N is
x_i = t_i - t_0 - i T (s), one sample per tick, tau0 = T. A constant rate
(any T) drops out of both deviations, which are second differences of x.
The estimators are allantools' (``oadev``, ``tdev``), at octave averaging
factors m = 1, 2, 4, ... up to N/4 (at least four independent spans of the
longest tau). Each point's confidence interval (68.3 %, one sigma, by
default) is the chi-squared interval of Greenhall's equivalent degrees of
freedom (``edf_greenhall``) for the noise type that the lag-1
autocorrelation identifies at that m (``autocorr_noise_id``; where fewer
than ``NOISE_ID_SAMPLES`` spans remain to identify it, the type found at
the largest m that had them). Slopes of log sigma against log tau tell the
noise: -1 white phase noise, -1/2 white frequency noise, 0 flicker
frequency, +1/2 a random walk of frequency.
"""

from __future__ import annotations

import math

import numpy as np

CONFIDENCE = 0.6826894921370859  # one sigma of a normal distribution
MIN_TICKS = 17  # 16 periods: tau0, 2 tau0 and 4 tau0 with at least four spans of the longest
# Spans of length m the lag-1 autocorrelation identifies the noise from. NIST
# SP 1065 (Riley) puts the minimum near 30, but r1 from n samples is known
# to ~1/sqrt(n), and alpha = -2 rho (rho = r1/(1 + r1)) is rounded: with 32
# spans white frequency noise of 16384 ticks was taken for other types at
# m >= 512 in half the seeds tried, and the intervals there held the true
# deviation in 42-62 % of them instead of 68 %; with 128 spans, 60-78 %.
NOISE_ID_SAMPLES = 128

# The result columns, in order, with their units.
COLUMNS = (("tau_s", "s"), ("m", ""), ("oadev", ""), ("oadev_lo", ""), ("oadev_hi", ""), ("tdev_s", "s"),
           ("tdev_lo_s", "s"), ("tdev_hi_s", "s"), ("noise_alpha", ""), ("edf_oadev", ""), ("edf_tdev", ""))


def time_error(ticks) -> tuple[np.ndarray, float]:
    """(x, tau0): the time error (s) at each tick against the mean period, and that period (s)."""
    t = np.asarray(ticks, dtype=float)
    n = len(t) - 1
    period = (t[-1] - t[0]) / n
    return (t - t[0]) - period * np.arange(n + 1), period


def averaging_factors(n_samples: int) -> list[int]:
    """Octaves m = 1, 2, 4, ... with m <= (n_samples - 1) / 4."""
    out, m = [], 1
    while 4 * m <= n_samples - 1:
        out.append(m)
        m *= 2
    return out


def _noise_alphas(x: np.ndarray, factors: list[int]) -> list[int]:
    """The power-law exponent alpha of the frequency noise at each m (2: white
    phase, 0: white frequency, -1: flicker frequency, -2: random walk)."""
    import allantools  # imported where used: a run that asks for no stability never pays for it

    found: list[int | None] = []
    for m in factors:
        alpha = None
        if len(x) // m >= NOISE_ID_SAMPLES:
            try:
                alpha_int = allantools.autocorr_noise_id(x, af=m, data_type="phase")[0]
                alpha = int(max(-2, min(2, round(alpha_int)))) if math.isfinite(alpha_int) else None
            except Exception:  # allantools refuses too short a series: the neighbour's type below
                alpha = None
        found.append(alpha)
    known = [a for a in found if a is not None]
    fallback = known[-1] if known else 0
    out, last = [], None
    for a in found:
        last = a if a is not None else (last if last is not None else fallback)
        out.append(last)
    return out


def allan(ticks, confidence: float = CONFIDENCE) -> dict:
    """The stability of a tick log: ``{"columns": {name: [values]}, "units",
    "ticks", "mean_period_s", "confidence", "estimators"}``. `ticks`:
    increasing times, s, at least MIN_TICKS of them (the caller checks)."""
    import warnings

    with warnings.catch_warnings(), np.errstate(divide="ignore", invalid="ignore"):
        # a perfect clock (every deviation 0) makes the noise identification
        # divide 0 by 0: its type is then unknown, not a warning on stderr
        warnings.simplefilter("ignore", RuntimeWarning)
        return _allan(ticks, confidence)


def _allan(ticks, confidence: float) -> dict:
    import allantools

    x, tau0 = time_error(ticks)
    factors = averaging_factors(len(x))
    rate = 1.0 / tau0
    taus = np.asarray(factors, dtype=float) * tau0
    t_ad, ad, _, _ = allantools.oadev(x, rate=rate, data_type="phase", taus=taus)
    t_td, td, _, _ = allantools.tdev(x, rate=rate, data_type="phase", taus=taus)
    if len(t_ad) != len(factors) or len(t_td) != len(factors):
        raise RuntimeError(f"allantools gave {len(t_ad)} and {len(t_td)} taus for {len(factors)} asked")
    alphas = _noise_alphas(x, factors)
    cols: dict[str, list] = {name: [] for name, _ in COLUMNS}
    n = len(x)
    for m, tau, a, t, alpha in zip(factors, taus, ad, td, alphas):
        edf_a = float(allantools.edf_greenhall(alpha=alpha, d=2, m=m, N=n, overlapping=True, modified=False))
        # tdev = tau mdev / sqrt(3): the interval of mdev, scaled
        edf_t = float(allantools.edf_greenhall(alpha=alpha, d=2, m=m, N=n, overlapping=True, modified=True))
        a_lo, a_hi = allantools.confidence_interval(a, edf_a, ci=confidence)
        t_lo, t_hi = allantools.confidence_interval(t, edf_t, ci=confidence)
        for name, value in (("tau_s", tau), ("m", m), ("oadev", a), ("oadev_lo", a_lo), ("oadev_hi", a_hi),
                            ("tdev_s", t), ("tdev_lo_s", t_lo), ("tdev_hi_s", t_hi), ("noise_alpha", alpha),
                            ("edf_oadev", edf_a), ("edf_tdev", edf_t)):
            cols[name].append(float(value) if name not in ("m", "noise_alpha") else int(value))
    return {"columns": cols, "units": dict(COLUMNS), "ticks": len(x), "mean_period_s": tau0,
            "confidence": confidence, "estimators": f"allantools {allantools.__version__}: oadev, tdev; "
                                                   "edf_greenhall with autocorr_noise_id"}


def log_slope(taus, devs, lo, hi, tau_range: tuple[float, float]) -> tuple[float, float]:
    """(slope, standard error) of log dev against log tau between the two
    ends of `tau_range` (the points nearest to them), from the two end
    points, each with the log half-width of its interval as its standard
    error (the intervals are one sigma). The points between are not
    averaged in: overlapping estimates at neighbouring taus are correlated,
    and a least-squares error over them would claim too much."""
    taus = np.asarray(taus, float)
    i = int(np.argmin(abs(np.log(taus / tau_range[0]))))
    j = int(np.argmin(abs(np.log(taus / tau_range[1]))))
    if i == j:
        raise ValueError("the tau range spans a single point")
    span = math.log(taus[j] / taus[i])
    slope = math.log(devs[j] / devs[i]) / span
    se = [0.5 * math.log(hi[k] / lo[k]) for k in (i, j)]
    return slope, math.hypot(*se) / abs(span)
