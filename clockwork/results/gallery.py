"""The gallery's index page: every figure with the papers' numbers beside ours."""

from __future__ import annotations

import math


def _fmt(x) -> str:
    if x is None:
        return "-"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, int):
        return str(x)
    if isinstance(x, float):
        return "nan" if not math.isfinite(x) else f"{x:.4g}"
    return str(x).replace("|", "\\|").replace("\n", " ")


def _wall(s: float) -> str:
    return f"{s:.1f} s" if s < 120 else f"{s / 60:.1f} min"


def index_markdown(g: dict) -> str:
    lines = ["# clockwork gallery", ""]
    n_ok = sum(e["status"] == "ok" for e in g["scenes"])
    lines.append(f"{n_ok} of {len(g['scenes'])} scenes ran"
                 f"{' (quick settings where scenarios/quick.json has them)' if g['quick'] else ''}; "
                 f"total wall time {_wall(g['wall_time_s'])}.")
    lines += ["", "| scene | reproduces | wall time | status |", "|---|---|---|---|"]
    for e in g["scenes"]:
        status = e["status"] + (" (quick)" if e.get("quick") and e.get("overrides") else "")
        lines.append(f"| [{e['scene']}](#{e['scene'].lower()}) | {_fmt(e.get('reproduces') or '')} | "
                     f"{_wall(e['wall_time_s'])} | {status} |")
    for e in g["scenes"]:
        lines += ["", f"## {e['scene']}", ""]
        if e.get("title"):
            lines.append(f"**{_fmt(e['title'])}**" + (f" - reproduces {e['reproduces']}" if e.get("reproduces") else ""))
            lines.append("")
        lines.append(f"Wall time {_wall(e['wall_time_s'])}"
                     + (f"; overrides: `{' '.join(e['overrides'])}`" if e.get("overrides") else "")
                     + (f"; {e['points']} points" if e.get("points", 1) and e.get("points", 1) > 1 else "")
                     + (f", {e['points_failed']} failed" if e.get("points_failed") else "") + ".")
        if e["status"] != "ok":
            lines += ["", f"**Failed:** {_fmt(e.get('error'))}"]
            continue
        heads = e.get("headlines") or []
        if heads:
            lines += ["", "| quantity | paper | ours | unit | tolerance | note |", "|---|---|---|---|---|---|"]
            for h in heads:
                paper = _fmt(h.get("paper")) + (" (scene as written; not comparable)"
                                                 if h.get("comparable") is False else "")
                lines.append(f"| {_fmt(h.get('quantity'))} | {paper} | {_fmt(h.get('ours'))} | "
                             f"{_fmt(h.get('unit') or '')} | {_fmt(h.get('tolerance'))} | {_fmt(h.get('note') or '')} |")
        for png in e.get("files", []):
            lines += ["", f"![{png}]({e['scene']}/{png})"]
    return "\n".join(lines) + "\n"
