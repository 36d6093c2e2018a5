"""Plot kinds of the chaos scenes (Ziemkiewicz Figs. 8-11).

``phase_space`` (x, y, window), ``vibration_time`` (window),
``poincare_map``, ``rate_error``, ``lyapunov``, ``step_accuracy``.
"""

from __future__ import annotations

import math

import numpy as np

from ...scene.kinds import Invalid
from .registry import check_keys, display, register, subplots, title_of


def _plot_keys(t: dict) -> dict:
    # Imported on use: the plot process starts without the engine and fmpy (background).
    from ...analyses import keys

    out = check_keys(t, strings=("x", "y", "title"))
    if "window" in t:
        w = t["window"]
        if not (isinstance(w, list) and len(w) == 2):
            raise Invalid("window", "[from, to] times")
        out["window"] = [keys.time("window", w[0], positive=False), keys.time("window", w[1])]
        if out["window"][1] <= out["window"][0]:
            raise Invalid("window", "[from, to] with from < to")
    return out


@register("phase_space", {"x", "y", "window"}, _plot_keys, run="series", columns={"x": None, "y": None})
def plot_phase_space(scene, r, spec):
    """A trajectory in degrees, coloured by time; +-phi_r marked when x is the pendulum angle."""
    # Imported on use: the plot process starts without the engine and fmpy (background).
    from ...analyses.context import find_component, parameters

    s = r["series"]
    t = np.asarray(s["time"])
    sel = np.ones(len(t), bool)
    if spec.get("window"):
        a, b = spec["window"]
        sel = (t >= a) & (t <= b)
    x, xl = display(scene, spec["x"], np.asarray(s[spec["x"]])[sel])
    y, yl = display(scene, spec["y"], np.asarray(s[spec["y"]])[sel])
    fig, ax = subplots(figsize=(6, 5.5))
    from matplotlib.collections import LineCollection

    pts = np.column_stack([x, y])
    lc = LineCollection(np.stack([pts[:-1], pts[1:]], axis=1), cmap="viridis", lw=0.6)
    lc.set_array(t[sel][:-1])
    ax.add_collection(lc)
    ax.autoscale()
    fig.colorbar(lc, ax=ax, label="time (s)")
    ax.plot(x[:1], y[:1], "ko", ms=4, label="start")
    esc = find_component(scene, "GrasshopperEscapement")
    pend = find_component(scene, "Pendulum")
    if esc and pend and spec["x"] == f"{pend}.phi":
        phi_r = math.degrees(parameters(scene)[esc]["phi_r"])
        for v in (phi_r, -phi_r):
            ax.axvline(v, color="0.4", ls="--", lw=0.8)
        ax.text(0.01, 0.01, "dashed: $\\pm\\alpha_r$ (torque switches: kinks)", transform=ax.transAxes,
                fontsize=7, color="0.3")
    ax.set_xlabel(xl)
    ax.set_ylabel(yl)
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(title_of(scene, spec), fontsize=10)
    return fig


@register("vibration_time", {"window"}, _plot_keys, run="series")
def plot_vibration_time(scene, r, spec):
    """a2 (deg) and the escapement torque (N.cm) against time (Fig. 9a)."""
    # Imported on use: the plot process starts without the engine and fmpy (background).
    from ...analyses.context import find_component

    s = r["series"]
    vib = find_component(scene, "MechanismVibration")
    esc = find_component(scene, "GrasshopperEscapement")
    pend = find_component(scene, "Pendulum")
    t = np.asarray(s["time"])
    sel = np.ones(len(t), bool)
    if spec.get("window"):
        a, b = spec["window"]
        sel = (t >= a) & (t <= b)
    fig, ax = subplots(figsize=(9, 4))
    ax.plot(t[sel], np.degrees(np.asarray(s[f"{vib}.a2"])[sel]), color="C0", lw=0.8,
            label="$\\alpha_2$ (vibration)")
    ax.plot(t[sel], np.degrees(np.asarray(s[f"{pend}.phi"])[sel]) * r["result"]["forced_gain_linear"],
            color="C2", lw=0.8, ls="--", label="$-C_2\\alpha_1/\\omega_{02}^2$ (quasi-static)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("$\\alpha_2$ (deg)", color="C0")
    tx = ax.twinx()
    tx.plot(t[sel], 100.0 * np.asarray(s[f"{esc}.tau"])[sel], color="C1", lw=0.9, label="torque $M_F$")
    tx.set_ylabel("torque $M_F$ (N.cm)", color="C1")
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = tx.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, loc="upper right", fontsize=8)
    ax.set_title(title_of(scene, spec), fontsize=10)
    return fig


@register("poincare_map", set(), _plot_keys)
def plot_poincare(scene, results, spec):
    """One panel per sweep point: (a2, a2dot) at the upward zero crossings of a1."""
    rows = [r for r in results if r and "series" in r and r["series"].get("a2")]
    if not rows:
        return None
    fig, axes = subplots(1, len(rows), figsize=(5 * len(rows), 4.6), squeeze=False)
    for ax, r in zip(axes[0], rows):
        s, res = r["series"], r["result"]
        ax.plot(np.degrees(s["a2"]), np.degrees(s["a2dot"]), ".", ms=2.5, color="C0")
        ax.set_xlabel("$\\alpha_2$ (deg)")
        ax.set_ylabel("$\\dot\\alpha_2$ (deg/s)")
        ax.set_title(f"$C_2$ = {res['C2']:g}: {res['n_points']} points, ring width "
                     f"{res.get('ring_width', math.nan):.3g}", fontsize=9)
        ax.ticklabel_format(style="sci", scilimits=(-3, 3))
    fig.suptitle(title_of(scene, spec), fontsize=10)
    return fig


@register("rate_error", set(), _plot_keys, run="series")
def plot_rate_error(scene, r, spec):
    s = r["series"]
    t = np.asarray(s["time"])
    fig, ax = subplots(figsize=(9, 4.5))
    ax.plot(t, s["momentary_s_per_day"], color="C0", lw=0.8, label="momentary error (per period)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("momentary rate error (s/day)", color="C0")
    ax.axhline(0.0, color="0.7", lw=0.5)
    tx = ax.twinx()
    tx.plot(t, s["accumulated_s"], color="C1", lw=1.2, label="accumulated error")
    tx.set_ylabel("accumulated time error (s)", color="C1")
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = tx.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, loc="upper right", fontsize=8)
    ax.set_title(title_of(scene, spec), fontsize=10)
    ax.text(0.01, 0.02, "reference: the same clock with $C_1 = C_2 = 0$, run in lockstep",
            transform=ax.transAxes, fontsize=7, color="0.3")
    return fig


@register("lyapunov", set(), _plot_keys)
def plot_lyapunov(scene, results, spec):
    rows = [r for r in results if r and "series" in r]
    if not rows:
        return None
    fig, (ax, bx) = subplots(2, 1, figsize=(8, 7), sharex=True)
    for k, r in enumerate(rows):
        s, res = r["series"], r["result"]
        t = np.asarray(s["time"])
        lab = f"$C_1$ = {res['C1']:g}, $C_2$ = {res['C2']:g}"
        ls = "-" if res["C2"] or res["C1"] else "--"
        for name, col, sym in (("lambda1", "C0", "$\\lambda_1$ (pendulum)"),
                               ("lambda2", "C1", "$\\lambda_2$ (vibration)")):
            y = np.asarray(s[name], dtype=float)
            if np.isfinite(y).any():
                ax.plot(t, y, ls, color=col, lw=1.0, label=f"{sym}, {lab}")
        for name, col in (("d1", "C0"), ("d2", "C1")):
            d = np.asarray(s[name], dtype=float)
            if (d > 0).any():
                bx.semilogy(t, np.where(d > 0, d, np.nan), ls, color=col, lw=0.8,
                            label=f"{name}, {lab}")
    ax.axhline(0.0, color="0.6", lw=0.5)
    ax.axhline(0.05, color="C1", lw=0.5, ls=":")
    ax.axhline(0.01, color="C0", lw=0.5, ls=":")
    ax.set_ylabel("fitted exponent over [0, t] (1/s)")
    ax.set_ylim(-0.05, 0.1)
    ax.legend(loc="upper right", fontsize=7)
    ax.text(0.01, 0.02, "dotted: the paper's 0.05 ($\\lambda_2$) and 0.01 ($\\lambda_1$)",
            transform=ax.transAxes, fontsize=7, color="0.3")
    bx.set_ylabel("twin distance (rad, phase space)")
    bx.set_xlabel("time (s)")
    bx.legend(loc="lower right", fontsize=7)
    ax.set_title(title_of(scene, spec), fontsize=10)
    return fig


@register("step_accuracy", set(), _plot_keys, run="series")
def plot_step_accuracy(scene, r, spec):
    s, res = r["series"], r["result"]
    h = np.asarray(s["h_s"])
    fig, ax = subplots(figsize=(11, 5.5))
    floor = 1e-16  # exact to round-off: drawn at the floor

    def draw(col, fmt, label, **kw):
        y = np.abs(np.asarray(s[col], dtype=float))
        ok = np.isfinite(y)
        if ok.any():
            ax.loglog(h[ok], np.maximum(y[ok], floor), fmt, label=label, **kw)

    draw("fixed_rel_err", "o-", "ours: DP5(4), fixed internal step h", color="C0")
    rcols = [c for c in s if c.startswith("rtol_")]
    for k, c in enumerate(rcols):
        rt = c[len("rtol_"):-len("_rel_err")]
        draw(c, "s--", f"ours: adaptive rtol {rt}, h = communication step", color=f"C{k + 2}", ms=4)
    draw("paper_a1_quantized_rel_err", "D-", "Eq. (A1), ticks at step resolution", color="C1")
    draw("paper_a1_interpolated_rel_err", "D:", "Eq. (A1), ticks interpolated", color="C1", mfc="none")
    for key, lab, ls in (("eq2_one_term_rel_err", "Eq. (2), one term", "-."),
                         ("eq2_two_term_rel_err", "Eq. (2), two terms", ":")):
        ax.axhline(abs(res[key]), color="0.4", ls=ls, lw=0.9, label=lab)
    ax.plot([res["default_master_step_s"]], [max(abs(res["default_rel_err"]), floor)], "k*", ms=12,
            label=f"ours at default settings (rtol {res['default_rtol']:g})")
    ax.axhline(1e-7, color="r", lw=0.5, ls="--")
    ax.text(h.min(), 1.3e-7, "paper: ~1e-7 at 100 us, ~10x less at 10 us", fontsize=7, color="r")
    ax.axhline(floor, color="0.8", lw=0.5)
    ax.text(h.max(), 1.3 * floor, "values below 1e-16 drawn at 1e-16", fontsize=6, color="0.5", ha="right")
    ax.set_xlabel("numerical step h (s)")
    ax.set_ylabel("$|E_C^{sim} - E_C^{AGM}|$ (relative)")
    ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=7)
    ax.set_title(title_of(scene, spec), fontsize=10)
    return fig
