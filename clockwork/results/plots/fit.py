"""The plot of `clockwork fit`: each measured column against the rows'
first set parameter (or the row number), the measurements with their
uncertainties and the fitted model, and below it the residuals."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .registry import display, legend, plain, subplots, unit_of


def draw_fit(scene, summary: dict, columns: list[str]):
    """A Figure from a fit's summary (``fit.residuals``, ``data.set``)."""
    rows = summary["fit"]["residuals"]
    set_names = list(summary["data"]["set"])
    n = len(columns)
    fig, axes = subplots(2, n, figsize=(5.0 * n + 1.0, 5.2), squeeze=False, sharex="col",
                         gridspec_kw={"height_ratios": [3, 1.3]})
    if set_names:
        x_all, x_label = display(scene, set_names[0], [r["parameters"][set_names[0]] for r in rows])
    else:
        x_all, x_label = np.arange(1, len(rows) + 1, dtype=float), "row"
    for j, c in enumerate(columns):
        top, bottom = axes[0][j], axes[1][j]
        picked = [i for i, r in enumerate(rows) if c in r]
        x = np.asarray([x_all[i] for i in picked], dtype=float)
        y = np.asarray([rows[i][c]["measured"] for i in picked], dtype=float)
        f = np.asarray([rows[i][c]["fitted"] for i in picked], dtype=float)
        s = [rows[i][c]["sigma"] for i in picked]
        err = None if any(v is None for v in s) else np.asarray(s, dtype=float)
        order = np.argsort(x, kind="stable")
        measured = top.errorbar(x, y, yerr=err, fmt="o", ms=4, color="C0", capsize=2, lw=0.8)
        fitted, = top.plot(x[order], f[order], "-", color="C3", lw=1.0, marker=".", ms=3)
        unit = unit_of(c)
        header = summary["data"]["measured"].get(c, c)
        source = "" if header == c else (f"= -({header})" if c in summary["data"].get("negated", []) else
                                         f"from {header}")
        top.set_ylabel(plain(f"{c} ({unit})" if unit else c) + (f"\n{plain(source)}" if source else ""))
        legend(top, [measured, fitted], ["measured" + (" +- sigma" if err is not None else ""), "fitted"],
               fontsize=8, loc="best")
        bottom.axhline(0.0, color="0.5", lw=0.6)
        bottom.errorbar(x, y - f, yerr=err, fmt="o", ms=3, color="C0", capsize=2, lw=0.8)
        bottom.set_ylabel("measured - fitted")
        bottom.set_xlabel(x_label)
    params = summary["fit"]["parameters"]
    shown = ", ".join(f"{plain(k)} = {p['value']:.5g}" + (f" +- {p['sigma']:.2g}" if p["identifiable"] else
                                                          " (not identifiable)") + (f" {p['unit']}" if p["unit"] else "")
                      for k, p in params.items())
    where = f"{Path(summary['scene']).stem}: fit to {Path(summary['data']['file']).name}"
    fig.suptitle(f"{plain(where)}\n{shown}; chi2/dof = "
                 + (f"{summary['fit']['reduced_chi2']:.3g}" if summary["fit"]["reduced_chi2"] is not None else "-"),
                 fontsize=9)
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 0.95))  # room for the two lines of the title
    return fig
