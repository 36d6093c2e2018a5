"""Plot kinds of the Hoyng scenes (Figs. 3-6, App. C).

``hoyng_rate_map``, ``hoyng_comparison``, ``hoyng_phi``, ``hoyng_jump``,
``hoyng_long_run``.
"""

from __future__ import annotations

import math

import numpy as np

from .registry import check_keys, curves, plain, register, subplots, title_of


def _convert_plot(t: dict) -> dict:
    # Imported on use: the plot process starts without the engine and fmpy (background).
    from ...analyses import keys

    out = check_keys(t, strings=("x", "title", "group", "theory"), booleans=("log_x",))
    for k in ("eps_max", "mu_max"):
        if k in t:
            out[k] = keys.positive_number(k, t[k])
    return out


_NAMED = {"A": (2.5e-4, 2e-5), "B": (2.5e-4, 4e-5), "C": (1.167245e-4, 1.5e-5)}


def _stationary_rows(results):
    """The rows a plot of these kinds draws (analyses.hoyng.common.stationary_rows), imported on use."""
    from ...analyses.hoyng.common import stationary_rows

    return stationary_rows(results)


@register("hoyng_rate_map", {"eps_max", "mu_max", "levels", "title", "file"}, _convert_plot)
def plot_rate_map(scene, results, spec):
    """Fig. 3: Eq. (20) in s/day over (eps, mu), lambda = k phi0 lines, simulated points."""
    # Imported on use: the plot process starts without the engine and fmpy (background).
    from ...analyses.context import find_component, parameters
    from ...analyses.hoyng.common import DAY, stationary_rows

    rows = stationary_rows(results)
    esc = find_component(scene, "GrasshopperEscapement")
    phi0 = parameters(scene)[esc]["phi_r"] if esc else 0.03
    eps_max = spec.get("eps_max", 3e-4)
    mu_max = spec.get("mu_max", 5e-5)
    E, M = np.meshgrid(np.linspace(eps_max / 400, eps_max, 300), np.linspace(mu_max / 400, mu_max, 300))
    x = 2.0 * M / (math.pi * E * phi0) - 1.0
    Z = np.where(x >= 0, -M * phi0 / (8 * math.pi * E) + E * np.sqrt(np.maximum(x, 0)), np.nan) * DAY
    fig, ax = subplots(figsize=(7, 5.5))
    levels = spec.get("levels", [-40, -30, -20, -10, -5, 0, 5, 10, 15, 20])
    neg = [lv for lv in levels if lv != 0]
    cs = ax.contour(E, M, Z, levels=neg, colors="k", linewidths=0.8)
    ax.clabel(cs, fmt="%g", fontsize=7)
    if 0 in levels:
        ax.contour(E, M, Z, levels=[0.0], colors="k", linewidths=1.2, linestyles="--")
    e = np.linspace(0, eps_max, 100)
    for k in (1, 2, 3):
        ax.plot(e, math.pi * e * k * k * phi0 / 2.0, ":", color="C0", lw=1.0)
        ek = min(eps_max, 2 * mu_max / (math.pi * k * k * phi0)) * 0.92
        ax.text(ek, math.pi * ek * k * k * phi0 / 2.0, f"$\\lambda = {k if k > 1 else ''}\\varphi_0$",
                color="C0", fontsize=8, ha="right", va="bottom")
    if rows:
        xs = [r["result"]["eps"] for r in rows]
        ys = [r["result"]["mu"] for r in rows]
        ax.plot(xs, ys, "o", ms=5, mfc="none", color="C3", label="co-simulated (right panel)")
    for name, (ex, mx) in _NAMED.items():
        if ex <= eps_max and mx <= mu_max:
            ax.plot(ex, mx, "k.", ms=6)
            ax.annotate(name, (ex, mx), textcoords="offset points", xytext=(4, 4), fontsize=9)
    ax.set_xlim(0, eps_max)
    ax.set_ylim(0, mu_max)
    ax.set_xlabel("friction $\\varepsilon$")
    ax.set_ylabel("torque $\\mu$ (units of m g L)")
    ax.set_title(title_of(scene, spec), fontsize=10)
    ax.text(0.99, 0.01, f"$\\dot\\psi - 1$ (s/day), Eq. (20), $\\varphi_0$ = {phi0:g}; below $\\lambda = \\varphi_0$ it stalls",
            transform=ax.transAxes, fontsize=7, ha="right")
    if rows:
        ax.legend(loc="upper left", fontsize=8)
    return fig


@register("hoyng_comparison", {"x", "group", "theory", "log_x", "title", "file"}, _convert_plot, rows=_stationary_rows,
          columns={"x": "eps", "group": None, "theory": "rate_theory"})
def plot_comparison(scene, rows, spec):
    """Simulated stationary rate against the closed form (s/day), and their difference."""
    # Imported on use: the plot process starts without the engine and fmpy (background).
    from ...analyses.hoyng.common import DAY, hoyng_components

    xk, gk = spec.get("x", "eps"), spec.get("group")
    theory = spec.get("theory", "rate_theory")
    groups = curves([r["result"] for r in rows], lambda res: res.get(gk) if gk else None)
    fig, (ax, bx) = subplots(2, 1, figsize=(7, 6.5), sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    for k, (g, rs) in enumerate(sorted(groups.items(), key=lambda kv: (kv[0] is None, kv[0] or 0))):
        rs = sorted(rs, key=lambda r: r[xk])
        x = np.array([r[xk] for r in rs])
        sim = np.array([r["rate_sim"] for r in rs]) * DAY
        th = np.array([r[theory] for r in rs]) * DAY
        label = "" if g is None else f"{plain(gk)} = {g:g}"
        c = f"C{k}"
        ax.plot(x, th, "-", color=c, lw=1.0, label=label or theory)
        ax.plot(x, sim, "o", color=c, ms=5, mfc="none", label="co-simulation" if k == 0 else None)
        avg_keys = [f"rate_{a}" for a in hoyng_components(scene)[2] if f"rate_{a}" in rs[0]]
        for ak in avg_keys:
            ax.plot(x, np.array([r[ak] for r in rs]) * DAY, "x", color=c, ms=5,
                    label=f"{ak[5:]} (AveragedPendulum FMU)" if k == 0 else None)
        bx.plot(x, (sim - th) / DAY, "o-", color=c, ms=4, mfc="none", lw=0.8)
        bound = np.array([r["next_order_bound"] for r in rs])
        bx.plot(x, bound, ":_", color=c, lw=0.8, ms=8)
        bx.plot(x, -bound, ":_", color=c, lw=0.8, ms=8)
    ax.set_ylabel("$\\dot\\psi - 1$ (s/day)")
    ax.axhline(0, color="0.7", lw=0.5)
    ax.legend(loc="best", fontsize=7)
    ax.set_title(title_of(scene, spec), fontsize=10)
    bx.set_ylabel("simulation - theory\n(relative rate)")
    bx.set_xlabel(plain(xk))
    bx.axhline(0, color="0.7", lw=0.5)
    bx.text(0.01, 0.03, "dotted / bars: $\\pm$(eps + |circular| + |escapement term|)$^2$, the second order; "
            f"lines: {theory}",
            transform=bx.transAxes, fontsize=7)
    if spec.get("log_x"):
        bx.set_xscale("log")
    return fig


@register("hoyng_phi", {"title", "file"}, _convert_plot, run="phi_series")
def plot_phi(scene, r, spec):
    """Fig. 4: the pendulum angle around the torque jump (nothing to see)."""
    # Imported on use: the plot process starts without the engine and fmpy (background).
    from ...analyses.context import find_component, parameters
    from ...analyses.hoyng.common import TWO_PI

    t = np.asarray(r["phi_series"]["time_s"])
    phi = np.asarray(r["phi_series"]["phi_rad"])
    w0 = math.sqrt(parameters(scene)[find_component(scene, "Pendulum")]["g"] /
                   parameters(scene)[find_component(scene, "Pendulum")]["L"])
    res = r["result"]
    fig, (ax, bx) = subplots(2, 1, figsize=(7, 5.5))
    per = w0 * t / TWO_PI
    ax.plot(per, phi, "k-", lw=0.3)
    ax.axvline(res["jump_at_periods"], color="C3", ls=":", lw=0.8)
    ax.set_ylabel("$\\varphi$ (rad)")
    ax.set_title(title_of(scene, spec), fontsize=10)
    j = res["jump_at_periods"]
    win = (per > j - 4) & (per < j + 4)
    bx.plot(per[win], phi[win], "k.-", lw=0.5, ms=2)
    bx.axvline(j, color="C3", ls=":", lw=0.8)
    bx.set_xlabel("t / 2$\\pi$ (nominal periods)")
    bx.set_ylabel("$\\varphi$ (rad), zoom")
    bx.text(0.01, 0.03, f"torque {res['mu0']:g} -> {res['mu1']:g} at t/2$\\pi$ = {j:g} (dotted); "
            "points: communication points", transform=bx.transAxes, fontsize=7)
    return fig


@register("hoyng_jump", {"title", "file"}, _convert_plot, run="series")
def plot_jump(scene, r, spec):
    """Fig. 5: rate (Eq. 22) and amplitude after the torque jump, with Eqs. (16), (18)."""
    s = r["series"]
    per, rate = np.asarray(s["periods"]), np.asarray(s["rate"])
    fig, (ax, bx) = subplots(2, 1, figsize=(7, 6.5), sharex=True)
    ax.plot(per, rate, "k-", lw=0.8, label="co-simulation, Eq. (22)")
    k = np.linspace(0, len(per) - 1, 25).astype(int)
    ax.plot(per[k], np.asarray(s["rate_eq16_eq18"])[k], "D", ms=4, mfc="none", color="C3",
            label="Eq. (16) with $\\lambda$ from Eq. (18)")
    ax.set_ylabel("$\\dot\\psi - 1$")
    ax.legend(loc="lower right", fontsize=8)
    ax.set_title(title_of(scene, spec), fontsize=10)
    res = r["result"]
    ax.text(0.01, 0.03, f"$\\Delta\\psi$: {res.get('delta_psi_sim', float('nan')):.4f} (co-simulation), "
            f"{res['delta_psi_eq']:.4f} (Eqs. 16, 18)", transform=ax.transAxes, fontsize=8)
    bx.plot(per, s["amplitude_rad"], "k-", lw=0.8, label="co-simulation (turning points)")
    bx.plot(per[k], np.asarray(s["amplitude_eq18_rad"])[k], "D", ms=4, mfc="none", color="C3",
            label="Eq. (18)")
    bx.set_ylabel("amplitude $\\lambda$ (rad)")
    bx.set_xlabel("t / 2$\\pi$ (nominal periods)")
    bx.legend(loc="lower right", fontsize=8)
    return fig


@register("hoyng_long_run", {"title", "file"}, _convert_plot, run="series")
def plot_long_run(scene, r, spec):
    """Fig. 6: psi_p - t (top) and psi_p - psi_m (bottom), in cycles."""
    s = r["series"]
    res = r["result"]
    per = np.asarray(s["periods"])
    diffs = [k for k in s if k.startswith("psi_p_minus_psi_")]
    model = [k for k in s if k.startswith("psi_") and k.endswith("_minus_t_cycles") and k != "psi_p_minus_t_cycles"]
    nrows = 2 if diffs else 1
    fig, axes = subplots(nrows, 1, figsize=(7, 3.2 * nrows + 0.5), sharex=True, squeeze=False)
    ax = axes[0][0]
    if "psi_p_minus_t_cycles" in s:
        ax.plot(per, s["psi_p_minus_t_cycles"], "k-", lw=0.6, label="$\\psi_p - t$ (co-simulated pendulum)")
    for k in model:
        name = k[len("psi_"):-len("_minus_t_cycles")]
        ax.plot(per, s[k], "-", lw=0.6, label=f"$\\psi_m - t$ ({name})")
    ns = res.get("noise_start_periods")
    if ns:
        for a in axes[:, 0]:
            a.axvline(ns, color="0.4", ls=":", lw=0.8)
    ax.set_ylabel("cycles")
    ax.legend(loc="upper left", fontsize=7)
    ax.set_title(title_of(scene, spec), fontsize=10)
    if diffs:
        bx = axes[1][0]
        for k in diffs:
            name = k[len("psi_p_minus_psi_"):-len("_cycles")]
            circ = res.get(f"circular_{name}")
            lab = {0: "Eq. (16), $-\\lambda^2/16$", 1: "Eq. (A1) circular term"}.get(circ, "")
            bx.plot(per, s[k], "-", lw=0.8, label=f"$\\psi_p - \\psi_m$ ({name}: {lab})")
        bx.set_ylabel("cycles")
        bx.legend(loc="upper left", fontsize=7)
    axes[-1][0].set_xlabel("t / 2$\\pi$ (nominal periods)")
    return fig
