"""The benchmark's outputs: bench.csv, bench.md and the work-precision plot."""

from __future__ import annotations

import csv
import dataclasses
import math
from pathlib import Path


from .config import BenchConfig, Row, TARGET_S_PER_DAY, fmt


PROBLEM_TITLES = {
    "fig4a_5deg": ("Fig. 4(a) clock, 5 deg: steady-state rate error", "s/day"),
    "fig4a_7deg": ("Fig. 4(a) clock, 7 deg: steady-state rate error", "s/day"),
    "fig2b_chronometer": ("Fig. 2(b) chronometer, 5 deg: steady-state rate error", "s/day"),
    "hoyng": ("Hoyng torque jump: time error at tick 1000", "s"),
    "chaos_rate": ("Chaotic clock (Z Sec. VIII): mean-rate error", "s/day"),
    "chaos_a2rms": ("Chaotic clock (Z Sec. VIII): a2 rms error", "relative"),
    "chaos_lambda2": ("Chaotic clock (Z Sec. VIII): lambda2 error (twin runs)", "1/s"),
    "model_exchange": ("Free pendulum as a Model Exchange FMU: time error of tick N", "s"),
}


CSV_FIELDS = ["problem", "family", "tool", "label", "step_s", "rtol", "error", "unit", "wall_s", "repeats",
              "status", "note"]


def write_csv(path: Path, rows: list[Row]) -> None:
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=CSV_FIELDS)
        w.writeheader()
        for r in rows:
            d = dataclasses.asdict(r)
            w.writerow({k: ("" if d[k] is None or (isinstance(d[k], float) and math.isnan(d[k])) else d[k])
                        for k in CSV_FIELDS})


def plot_work_precision(path: Path, rows: list[Row], info: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    problems = [p for p in PROBLEM_TITLES if any(r.problem == p for r in rows)]
    if not problems:
        return
    ncol = min(3, len(problems))
    nrow = math.ceil(len(problems) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(6.2 * ncol, 4.8 * nrow), squeeze=False)
    families = list(dict.fromkeys(r.family for r in rows))
    cmap = plt.get_cmap("tab20")
    markers = {"clockwork": "o", "scipy": "x", "fmpy": "s", "libcosim": "D", "ecos": "^"}
    handles = {}
    for ax, prob in zip(axes.flat, problems):
        title, unit = PROBLEM_TITLES[prob]
        for fam in families:
            # In the order the family sweeps its setting (a line per family).
            pts = [(r.wall_s, r.error) for r in rows
                   if r.problem == prob and r.family == fam and r.status == "ok"
                   and math.isfinite(r.error) and math.isfinite(r.wall_s)]
            if not pts:
                continue
            tool = next(r.tool for r in rows if r.family == fam)
            x = [max(p[0], 1e-4) for p in pts]
            y = [max(p[1], 1e-14) for p in pts]  # an exact zero still shows
            style = "--" if fam.startswith("plain long run") else "-"
            (line,) = ax.plot(x, y, style, marker=markers.get(tool, "o"), color=cmap(families.index(fam) % 20),
                              ms=5, lw=1.2, label=fam)
            handles.setdefault(fam, line)
        if prob in ("fig4a_5deg", "fig4a_7deg", "fig2b_chronometer"):
            ax.axhline(TARGET_S_PER_DAY, color="k", lw=0.8, ls=":")
            ax.text(ax.get_xlim()[0] if ax.lines else 1e-3, TARGET_S_PER_DAY, " 1e-3 s/day", va="bottom", fontsize=7)
        floor = (info.get("chaos") or {}).get("floor", {})
        if prob == "chaos_rate" and floor:
            ax.axhline(floor["rate_s_per_day"], color="grey", lw=0.8, ls=":")
        if prob == "chaos_a2rms" and floor:
            ax.axhline(floor["a2_rms_relative"], color="grey", lw=0.8, ls=":")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_xlabel("wall time per run (s)")
        ax.set_ylabel(f"error ({unit})")
        ax.set_title(title, fontsize=9)
        ax.grid(True, which="major", alpha=0.3)
    for ax in list(axes.flat)[len(problems):]:
        ax.axis("off")
    fig.tight_layout()
    fig.legend(list(handles.values()), list(handles.keys()), loc="upper center", bbox_to_anchor=(0.5, 0.0),
               ncol=3, fontsize=7, frameon=False)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)


def _md_table(header: list[str], body: list[list]) -> list[str]:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(fmt(c).replace("|", "\\|") for c in row) + " |" for row in body]
    return out


def write_markdown(path: Path, cfg: BenchConfig, rows: list[Row], checks: list[dict], info: dict,
                   targets: dict, command: str) -> None:
    L = [f"# clockwork bench ({cfg.name})", ""]
    m = info["machine"]
    L += [f"Command: `{command}`  ", f"Date: {info['date']}, wall time {info['wall_s']:.0f} s  ",
          f"Machine: {m['cpus']} CPUs, {m['platform']}, Python {m['python']}; load average "
          f"{m['load_start']} at the start, {m['load_end']} at the end (the machine is shared: absolute times are "
          f"noisy, ratios measured side by side in this run are the better numbers)", ""]
    L += ["## Reference agreement (checked before anything is measured against the reference)", ""]
    L += _md_table(["check", "value", "bound", "unit", "ok", "bound from"],
                   [[c["check"], c["value"], c["bound"], c["unit"], "yes" if c["ok"] else "**NO**", c["reason"]]
                    for c in checks])
    L.append("")
    if "steady_points" in info:
        if "build_s" in info:
            L += [f"Building and freeing the Pendulum + escapement system alone takes {info['build_s'] * 1e3:.1f} ms "
                  "(median); every clockwork row of the steady-state problems includes it.", ""]
        L += ["Operating points (torques refined on the reference, rtol 1e-12):", ""]
        L += _md_table(["point", "torque (N.m)", "mean amplitude (deg)", "E_T reference (s/day)",
                        "reference wall (s)"],
                       [[k, v["torque_Nm"], v["amplitude_deg"], v["E_T_s_per_day"], v["wall_s"]]
                        for k, v in info["steady_points"].items()])
        L.append("")
    if info.get("hoyng"):
        hy = info["hoyng"]
        L += [f"Hoyng reference: tick {cfg.hoyng_ticks} at {hy['tick_s']!r} s (rtol 1e-11 differs by "
              f"{hy['rtol_1e-11_minus_1e-12_s']:.2g} s), {hy['wall_s']:.1f} s wall.", ""]
    if info.get("chaos"):
        ch = info["chaos"]
        ref = ch["reference"]
        L += [f"Chaos reference ({ch['t_end_s']:g} s, statistics from {ch['transient_s']:g} s on): mean rate "
              f"{ref['rate_s_per_day']:.6g} s/day over {ref['ticks']} ticks, a2 rms {ref['a2_rms']:.6g} rad; "
              f"{ch['wall_s']:.1f} s wall. Statistics floor (the same reference from 1e-6 deg more): "
              f"{ch['floor']['rate_s_per_day']:.2g} s/day, {ch['floor']['a2_rms_relative']:.2g} relative in the "
              f"a2 rms. Errors at or below the floor mean the trajectory is followed. lambda2 of the reference "
              f"twins (1e-6 deg apart, fitted over [0, {ch['t_end_s']:g}] s): "
              f"{ch['lambda2_reference_per_s']:.4g} 1/s; the lambda2 rows run the twin too and are not "
              f"measured for the peers.", ""]
    if info.get("model_exchange"):
        mx = info["model_exchange"]
        L += [f"Model Exchange reference: tick {mx['ticks']} of the free pendulum (6 deg, Q = 1000) at "
              f"{mx['tick_s']!r} s (scipy DOP853, rtol 1e-13, the crossing located); the FMU is {mx['fmu']}.", ""]
    if targets:
        L += ["## Targets", ""]
        L += _targets_md(targets)
    L += ["## Rows", "",
          "Error against the reference; wall time is the median of the repeats (clockwork and scipy: in this "
          "process, building and freeing the FMU instances included; peers: peer_tool.py in its subprocess "
          "after the tool's imports, loading the FMUs included; the note gives the whole process). "
          "Fixed-step peers start on the reference's periodic orbit, which only the "
          "reference knows, and are measured over "
          f"{cfg.peer_periods} periods: the protocol most favourable to them.", ""]
    for prob, (title, unit) in PROBLEM_TITLES.items():
        rs = [r for r in rows if r.problem == prob]
        if not rs:
            continue
        L += [f"### {title}", ""]
        L += _md_table(["family", "tool", "setting", f"error ({unit})", "wall (s)", "runs", "status", "note"],
                       [[r.family, r.tool, r.label, r.error, r.wall_s, r.repeats, r.status, r.note] for r in rs])
        L.append("")
    path.write_text("\n".join(L) + "\n")


def cfg_periods(r: Row) -> str:
    return r.label.split(", ")[-1] if "periods" in r.label else "run"


def _targets_md(t: dict) -> list[str]:
    L = []
    for e in t.get("speed", []):
        best = e["clockwork"]
        L.append(f"- {e['problem']}: clockwork's shooting with default settings, fastest within 1e-3 s/day: "
                 + (f"{best.label}: {best.error:.2g} s/day in {best.wall_s * 1e3:.1f} ms" if best else "none"))
        for tool, p in e["peers"].items():
            if "row" not in p:
                L.append(f"  - {tool}: {p['status']}")
            elif p["reaches"]:
                L.append(f"  - {tool}: reaches it ({p['row'].label}: {p['row'].error:.2g} s/day) in "
                         f"{p['row'].wall_s:.3g} s: **{p['ratio']:.3g} x** clockwork's time")
            else:
                r = p["row"]
                est = p.get("estimate") or {}
                more = ""
                if est.get("step_s"):
                    more = (f"; error ~ h^{est['order']:.2f}, 1e-3 s/day would need h ~ {est['step_s']:.2g} s, "
                            f"~{est['wall_s']:.3g} s for the same {cfg_periods(r)}")
                L.append(f"  - {tool}: does not reach it; best {r.error:.3g} s/day ({r.label}, {r.wall_s:.3g} s)"
                         + more)
    f4 = t.get("fig4a")
    if f4:
        if f4.get("status") == "ok":
            L.append(f"- `clockwork run scenarios/ziemkiewicz_fig4a.toml` (CLOCKWORK_CACHE=off), whole process: "
                     f"median {f4['median_wall_s']:.2f} s over {len(f4['process_wall_s'])} runs "
                     f"({', '.join(f'{w:.2f}' for w in f4['process_wall_s'])}), {f4['points']} points: "
                     f"**{f4['wall_per_point_s']:.3f} s per point** (target 0.2 s); inside the run "
                     f"{f4['in_run_wall_s']:.2f} s. Largest |E_T - reference| over the "
                     f"{f4['points_compared']} points: **{f4['max_error_s_per_day']:.2g} s/day** (target 1e-3).")
        else:
            L.append(f"- fig4a run: {f4['status']}")
    bm = t.get("bench_master")
    if bm:
        if bm.get("status") == "ok":
            L += ["- `python benchmarks/bench_master.py --steps 20000 --repeats 5` (target: master overhead "
                  "<= 3 us per FMU per step, the last column):", ""] + ["  " + x for x in bm["table"].splitlines()]
        else:
            L.append(f"- bench_master: {bm['status']}")
    f6 = t.get("fig6")
    if f6:
        if f6.get("status") == "ok":
            runs = ", ".join(f"{n} periods {w:.1f} s" for n, w in f6["runs"])
            L.append(f"- Hoyng Fig. 6 as a full co-simulation (4.8e6 periods, noise on): from `clockwork run "
                     f"scenarios/hoyng_fig6.toml --set experiment.stop=<N 2pi> --set escapement.noise_start=0` "
                     f"({runs}): {f6['per_period_ms']:.3f} ms per period, estimate **{f6['estimate_s']:.0f} s** "
                     f"(target < 1000 s).")
        else:
            L.append(f"- Hoyng Fig. 6: {f6['status']}")
    L.append("")
    return L
