"""The stability plot: the overlapping Allan deviation and the time
deviation of a run's ticks against tau, log-log, with their confidence
intervals (clockwork.analyses.stability). ``[[plot]] kind = "stability"``
in a scene whose run records ticks (record.ticks, the ticks analysis);
`clockwork stability` draws the same figure for any tick log."""

from __future__ import annotations

from pathlib import Path

from .registry import check_keys, register, subplots


def figure(result: dict, origin: str):
    """The figure of an ``analyses.stability.allan`` result; None when no
    deviation is above 0 (a perfect clock: nothing to draw on log axes)."""
    c = result["columns"]
    if not any(v > 0 for v in c["oadev"]) or not any(v > 0 for v in c["tdev_s"]):
        return None
    fig, (ax1, ax2) = subplots(1, 2, figsize=(10, 4))
    for ax, key, lo, hi, label in ((ax1, "oadev", "oadev_lo", "oadev_hi", "overlapping Allan deviation"),
                                   (ax2, "tdev_s", "tdev_lo_s", "tdev_hi_s", "time deviation (s)")):
        y = [float(v) for v in c[key]]
        err = [[a - b for a, b in zip(y, c[lo])], [b - a for a, b in zip(y, c[hi])]]
        ax.errorbar(c["tau_s"], y, yerr=err, fmt="o-", ms=3, capsize=2)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("tau (s)")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"{Path(origin).name}: {result['ticks']} ticks, mean period {result['mean_period_s']:.6g} s "
                 f"(intervals {100 * result['confidence']:.3g} %)", fontsize=10)
    return fig


@register("stability", set(), lambda t: check_keys(t, strings=("title",)), run="ticks")
def stability(scene, r, spec):
    from ...analyses import stability as st  # allantools: imported where drawn

    ticks = r.get("ticks") or []
    if len(ticks) < st.MIN_TICKS:
        return None
    fig = figure(st.allan(ticks), str(scene.path))
    if fig is not None and spec.get("title"):
        fig.suptitle(spec["title"], fontsize=10)
    return fig
