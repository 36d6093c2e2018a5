"""Plot kinds of the Ziemkiewicz scenes (Figs. 1-7), in the paper's units (deg, s/day).

``period_amplitude`` (free_period sweep), ``rate_errors`` (y: error
columns, dashed: columns drawn dashed, torque: bool), ``recoil``
(steady_orbit), ``contour`` (x, y: sweep parameters, z: result column,
levels, log_x, marker = [x, y] in SI), ``curves`` (x, y, group: sweep
parameters that make a curve, dashed_if: one of them, dashed when
non-zero), ``disturbance``.
"""

from __future__ import annotations

import math

import numpy as np

from ...physics import analytic
from ...scene.kinds import Invalid
from .registry import check_keys, curves, display, legend, plain, register, subplots, title_of


ERROR_LABELS = {
    "E_T_s_per_day": "$E_T$ (simulated)",
    "E_C_s_per_day": "$E_C$ (AGM)",
    "E_E_s_per_day": "$E_E = E_T - E_C$",
    "E_E_B7_s_per_day": "$E_E$ Eq. (B7)",
    "E_E_right_s_per_day": "$E_E$ vs right amplitude",
    "E_E_left_s_per_day": "$E_E$ vs left amplitude",
}


AXIS_LABELS = {"torque": "driving torque $M_F$ (N.cm)", "Q": "quality factor Q"}


def _convert_plot(t: dict) -> dict:
    out = check_keys(t, strings=("x", "z", "title", "dashed_if"), string_lists=("y", "dashed", "group"),
                     booleans=("torque", "log_x"))
    if "marker" in t:
        mk = t["marker"]
        if not (isinstance(mk, list) and len(mk) == 2 and all(isinstance(x, (int, float)) for x in mk)):
            raise Invalid("marker", "[x, y] in SI units")
    return out


def _orbit_rows(results):
    """The rows a plot of these kinds draws (analyses.ziemkiewicz.clock.orbit_rows), imported on use."""
    from ...analyses.ziemkiewicz.clock import orbit_rows

    return orbit_rows(results)


@register("period_amplitude", {"title", "file"}, _convert_plot)
def plot_period_amplitude(scene, results, spec):
    # Imported on use: the plot process starts without the engine and fmpy (background).
    from ...analyses.context import find_component, parameters
    from ...analyses.ziemkiewicz.clock import DEG, orbit_rows

    rows = sorted(orbit_rows(results), key=lambda r: r["result"]["amplitude_deg"])
    if not rows:
        return None
    A = np.array([r["result"]["amplitude_deg"] for r in rows])
    T = np.array([r["result"]["period_s"] for r in rows])
    rel = np.array([r["result"]["rel_diff_agm"] for r in rows])
    pend = find_component(scene, "Pendulum")
    pp = parameters(scene)[pend]
    a = np.linspace(0.0, A.max() * 1.02, 400)
    agm = np.array([analytic.exact_period(x * DEG, pp["L"], pp["g"]) for x in a])
    eq2 = np.array([analytic.series_period(x * DEG, pp["L"], pp["g"], terms=1) for x in a])
    fig, (ax, bx) = subplots(2, 1, figsize=(7, 6), sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    ax.plot(a, agm, "k-", lw=1.2, label="AGM (exact)")
    ax.plot(a, eq2, "r-", lw=1.0, label="Eq. (2), first order")
    ax.plot(A, T, "o", ms=4, mfc="none", color="C0", label="simulated (FMU ticks)")
    ax.set_ylabel("period T (s)")
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title(title_of(scene, spec), fontsize=10)
    bx.semilogy(A, np.maximum(np.abs(rel), 1e-17), "o", ms=4, mfc="none", color="C0",
                label="|simulated/AGM - 1|")
    eq2_rel = np.abs(eq2[1:] / agm[1:] - 1.0)
    bx.semilogy(a[1:], np.maximum(eq2_rel, 1e-17), "r-", lw=1.0, label="|Eq. (2)/AGM - 1|")
    bx.axhline(1e-10, color="0.5", ls=":", lw=0.8)
    bx.set_xlabel("amplitude A (deg)")
    bx.set_ylabel("relative difference")
    bx.legend(loc="lower right", fontsize=8)
    return fig


@register("rate_errors", {"y", "dashed", "torque", "title", "file"}, _convert_plot,
          columns={"y": ["E_T_s_per_day", "E_C_s_per_day", "E_E_s_per_day"], "dashed": None})
def plot_rate_errors(scene, results, spec):
    """Rate errors (s/day) against amplitude (deg), the torque (N.cm) on a second axis."""
    # Imported on use: the plot process starts without the engine and fmpy (background).
    from ...analyses.ziemkiewicz.clock import orbit_rows

    rows = sorted(orbit_rows(results), key=lambda r: r["result"]["amplitude_deg"])
    if not rows:
        return None
    A = [r["result"]["amplitude_deg"] for r in rows]
    fig, ax = subplots(figsize=(7, 4.5))
    ys = spec.get("y") or ["E_T_s_per_day", "E_C_s_per_day", "E_E_s_per_day"]
    blues = ["#08306b", "#2171b5", "#6baed6", "#9ecae1"]
    for k, y in enumerate(ys):
        v = [r["result"].get(y) for r in rows]
        ax.plot(A, [math.nan if x is None else x for x in v], "o-", ms=3, lw=1.2,
                color=blues[k % len(blues)], label=ERROR_LABELS.get(y, plain(y)))
    for y in spec.get("dashed", []):
        v = [r["result"].get(y) for r in rows]
        ax.plot(A, [math.nan if x is None else x for x in v], "--", lw=1.0, color="0.35",
                label=ERROR_LABELS.get(y, plain(y)))
    ax.axhline(0.0, color="0.7", lw=0.5)
    ax.set_xlabel("amplitude A (deg)")
    ax.set_ylabel("rate error (s/day, + = clock loses)")
    ax.set_title(title_of(scene, spec), fontsize=10)
    handles, labels = ax.get_legend_handles_labels()
    if spec.get("torque", True):
        tx = ax.twinx()
        tx.plot(A, [100.0 * r["result"]["torque_Nm"] for r in rows], "s-", ms=3, lw=1.2, color="C1",
                label="torque $M_F$")
        tx.set_ylabel("torque $M_F$ (N.cm)", color="C1")
        tx.tick_params(axis="y", colors="C1")
        h2, l2 = tx.get_legend_handles_labels()
        handles, labels = handles + h2, labels + l2
    ax.legend(handles, labels, loc="best", fontsize=8)
    stalled = len(results) - len(rows)
    if stalled:
        ax.text(0.01, 0.01, f"{stalled} torque(s) without a usable orbit omitted", transform=ax.transAxes,
                fontsize=7, color="0.4")
    return fig


@register("recoil", {"title", "file"}, _convert_plot, run="series")
def plot_recoil(scene, r, spec):
    """Angle (deg) and torque (N.cm) against time with the recoil phases shaded (Fig. 3)."""
    # Imported on use: the plot process starts without the engine and fmpy (background).
    from ...analyses.context import ESCAPEMENTS, find_component

    s = r["series"]
    pend = find_component(scene, "Pendulum")
    esc = find_component(scene, ESCAPEMENTS)
    t = np.asarray(s["time"])
    phi = np.degrees(np.asarray(s[f"{pend}.phi"]))
    tau = 100.0 * np.asarray(s[f"{esc}.tau"])
    rec = np.asarray(s["recoil"]) > 0.5
    fig, ax = subplots(figsize=(8, 4))
    # Shade each run of recoil samples.
    edges = np.flatnonzero(np.diff(np.concatenate([[0], rec.astype(int), [0]])))
    for a, b in zip(edges[::2], edges[1::2]):
        ax.axvspan(t[max(a - 1, 0)] if a > 0 else t[0], t[min(b, len(t) - 1)], color="0.85", lw=0)
    ax.plot(t, phi, color="C0", lw=1.2, label="angle $\\alpha$")
    phi_r = r["result"].get("phi_r_deg")
    if phi_r:
        for y in (phi_r, -phi_r):
            ax.axhline(y, color="0.3", ls="--", lw=0.8)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("angle (deg)", color="C0")
    tx = ax.twinx()
    tx.step(t, tau, where="post", color="C1", lw=1.2, label="torque $M_F$")
    tx.set_ylabel("torque (N.cm)", color="C1")
    lim = 1.3 * max(np.max(np.abs(tau)), 1e-12)
    tx.set_ylim(-lim, lim)
    alim = 1.3 * np.max(np.abs(phi))
    ax.set_ylim(-alim, alim)
    ax.set_title(title_of(scene, spec), fontsize=10)
    ax.text(0.01, 0.02, "shaded: recoil ($M_F$ opposes the motion); dashed: $\\pm\\alpha_r$",
            transform=ax.transAxes, fontsize=7, color="0.3")
    return fig


def _point_values(rows, key):
    return np.array([float(r["point"][key]) for r in rows])


@register("contour", {"x", "y", "z", "levels", "log_x", "marker", "title", "file"}, _convert_plot,
          columns={"x": None, "y": None, "z": "E_T_s_per_day"})
def plot_contour(scene, results, spec):
    """A result over a 2-D grid sweep: colour map and contour lines (Fig. 5)."""
    rows = [r for r in results if r and "point" in r]
    if not rows:
        return None
    xk, zk = spec["x"], spec.get("z", "E_T_s_per_day")
    yk = spec["y"][0] if isinstance(spec["y"], list) else spec["y"]
    xs = np.unique(_point_values(rows, xk))
    ys = np.unique(_point_values(rows, yk))
    Z = np.full((len(ys), len(xs)), np.nan)
    for r in rows:
        res = r.get("result", {})
        if res.get("stalled") or res.get("omitted") or res.get(zk) is None:
            continue
        i = int(np.searchsorted(ys, float(r["point"][yk])))
        j = int(np.searchsorted(xs, float(r["point"][xk])))
        Z[i, j] = res[zk]
    X, xl = display(scene, xk, xs)
    Y, yl = display(scene, yk, ys)
    xl, yl = (AXIS_LABELS.get(k.split(".")[-1], lab) for k, lab in ((xk, xl), (yk, yl)))
    fig, ax = subplots(figsize=(7, 5.5))
    finite = Z[np.isfinite(Z)]
    if finite.size == 0:
        return None
    levels = spec.get("levels")
    span = np.nanpercentile(np.abs(finite), 98) if finite.size else 1.0
    mesh = ax.pcolormesh(X, Y, np.ma.masked_invalid(Z), shading="nearest", cmap="RdBu_r",
                         vmin=-span, vmax=span)
    fig.colorbar(mesh, ax=ax, label=ERROR_LABELS.get(zk, plain(zk)) + " (s/day)")
    if levels:
        cs = ax.contour(X, Y, np.ma.masked_invalid(Z), levels=levels, colors="k", linewidths=0.8)
        ax.clabel(cs, fmt="%g", fontsize=7)
    if np.isnan(Z).any():
        ax.contourf(X, Y, np.isnan(Z).astype(float), levels=[0.5, 1.5], colors="none", hatches=["///"])
        ax.text(0.01, 0.01, "hatched: no orbit (amplitude would not exceed $\\alpha_r$)",
                transform=ax.transAxes, fontsize=7)
    if spec.get("log_x"):
        ax.set_xscale("log")
    if spec.get("marker"):
        mx, _ = display(scene, xk, [spec["marker"][0]])
        my, _ = display(scene, yk, [spec["marker"][1]])
        ax.plot(mx, my, "k*", ms=12, mfc="yellow", label="Fig. 4(a) operating point")
        ax.legend(loc="upper left", fontsize=8)
    ax.set_xlabel(xl)
    ax.set_ylabel(yl)
    ax.set_title(title_of(scene, spec), fontsize=10)
    return fig


@register("curves", {"x", "y", "group", "dashed_if", "title", "file"}, _convert_plot, rows=_orbit_rows,
          columns={"x": "amplitude_deg", "y": ["E_T_s_per_day"], "group": None, "dashed_if": None})
def plot_curves(scene, rows, spec):
    """One curve per combination of the `group` sweep parameters (Fig. 6)."""
    # Imported on use: the plot process starts without the engine and fmpy (background).
    from ...analyses.ziemkiewicz.clock import PROFILE_NAMES

    xk = spec.get("x", "amplitude_deg")
    yk = (spec.get("y") or ["E_T_s_per_day"])[0]
    group = spec.get("group") or []
    dashed_key = spec.get("dashed_if")
    by_group = curves(rows, lambda r: tuple(r["point"].get(g) for g in group))
    fig, ax = subplots(figsize=(7.5, 5))
    colours = {}
    lines, labels = [], []
    for key in sorted(by_group, key=lambda k: tuple(0 if v is None else v for v in k)):
        pts = sorted(by_group[key], key=lambda r: r["result"][xk])
        label_parts = []
        colour_key = []
        dashed = False
        for g, v in zip(group, key):
            if g.endswith(".profile"):
                label_parts.append(PROFILE_NAMES.get(int(v), f"profile {v}"))
                colour_key.append(v)
            elif g == dashed_key:
                dashed = bool(v)
                if v:
                    label_parts.append(f"+ drag $c_2$ = {v:.4g} N.m.s$^2$/rad$^2$")
            else:
                label_parts.append(f"{plain(g)} = {v:.4g}")
                colour_key.append(v)
        ck = tuple(colour_key)
        colours.setdefault(ck, f"C{len(colours)}")
        lines += ax.plot([p["result"][xk] for p in pts], [p["result"][yk] for p in pts],
                         "--" if dashed else "-", marker="o", ms=2.5, lw=1.2, color=colours[ck])
        labels.append(", ".join(label_parts))
    ax.axhline(0.0, color="0.7", lw=0.5)
    ax.set_xlabel("amplitude A (deg)" if xk == "amplitude_deg" else plain(xk))
    ax.set_ylabel(ERROR_LABELS.get(yk, plain(yk)) + " (s/day)")
    legend(ax, lines, labels, loc="best", fontsize=7)
    ax.set_title(title_of(scene, spec), fontsize=10)
    return fig


@register("disturbance", {"title", "file"}, _convert_plot, run="series")
def plot_disturbance(scene, r, spec):
    """Momentary period and amplitude change, and the accumulated time error (Fig. 7)."""
    s = r["series"]
    t = np.asarray(s["time"])
    rel = 100.0 * np.asarray(s["dT_over_T"])
    dA = np.asarray(s["dA_deg"])
    err = np.asarray(s["time_error_s"])
    tk = r["result"]["kick_start_s"]
    fig, (ax, bx) = subplots(2, 1, figsize=(8, 6), sharex=True, gridspec_kw={"height_ratios": [3, 2]})
    ax.plot(t, rel, color="C0", lw=1.0, label="period: $T/T_{stat} - 1$")
    ax.set_ylabel("momentary period change (%)", color="C0")
    ax.axvline(tk, color="0.6", ls=":", lw=0.8)
    tx = ax.twinx()
    tx.plot(t, dA, color="C1", lw=1.0, label="amplitude change")
    tx.set_ylabel("amplitude change $A - A_{stat}$ (deg)", color="C1")
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = tx.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, loc="upper right", fontsize=8)
    ax.set_title(title_of(scene, spec), fontsize=10)
    bx.plot(t, err, color="C2", lw=1.2)
    bx.axvline(tk, color="0.6", ls=":", lw=0.8)
    bx.set_ylabel("time error $\\Sigma(T - T_{stat})$ (s)")
    bx.set_xlabel("time (s)")
    res = r["result"]
    bx.text(0.01, 0.05, f"kick: g' = {res['g_factor']:g} g for {1e3 * res['kick_duration_s']:g} ms at "
            f"t = {tk:.3f} s, phi = {res['phi_at_kick_deg']:.3g} deg ({res['kick_at'].replace('_', ' ')})",
            transform=bx.transAxes, fontsize=7, color="0.3")
    return fig
