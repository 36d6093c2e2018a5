"""Every figure in one folder: `clockwork gallery --out DIR [--quick]`.

Runs every scene of a scenarios directory (default: the repository's
scenarios/) into DIR/<stem>/ with the ordinary runner, then writes

- DIR/index.md: per scene its title, what it reproduces, the wall time, the
  paper's headline numbers beside ours (summary.json "headlines") and every
  PNG it made;
- DIR/gallery.json: the same as data (status, wall time, headlines, files).

A scene that fails is reported in both and does not stop the others; the
command then exits with 1.

Quick mode: `<scenarios>/quick.json` maps a scene's file stem to a list of
`--set` overrides (the same syntax as `clockwork run --set`), e.g. a shorter
experiment for a long run. Scenes without an entry run in full.
"""

from __future__ import annotations

import json
import math
import time
import traceback
from pathlib import Path

from .errors import SceneError, SimulationError

REPO = Path(__file__).resolve().parents[1]


def quick_overrides(scenarios: Path) -> dict[str, list[str]]:
    f = scenarios / "quick.json"
    if not f.is_file():
        return {}
    try:
        data = json.loads(f.read_text())
    except json.JSONDecodeError as e:
        raise SceneError(f"not JSON: {e}", f) from None
    if not isinstance(data, dict):
        raise SceneError('expected {"scene_stem": ["key=value", ...]}', f)
    data = {k: v for k, v in data.items() if not k.startswith("_")}  # "_comment" and the like
    for k, v in data.items():
        if not (isinstance(v, list) and all(isinstance(x, str) for x in v)):
            raise SceneError('expected a list of "key=value" strings', f, k)
    return {k: list(v) for k, v in data.items()}


def run_gallery(out: Path, scenarios: Path | None = None, quick: bool = False, only: list[str] | None = None,
                workers: int | None = None, progress: bool = True) -> dict:
    from .runner import run_scene
    from .scene import load_scene

    out = Path(out)
    scenarios = Path(scenarios) if scenarios else REPO / "scenarios"
    out.mkdir(parents=True, exist_ok=True)
    files = sorted(scenarios.glob("*.toml"))
    if only:
        files = [f for f in files if f.stem in only]
    reduced = quick_overrides(scenarios) if quick else {}
    entries = []
    t_all = time.perf_counter()
    for f in files:
        entry = {"scene": f.stem, "file": str(f), "overrides": reduced.get(f.stem, []),
                 "quick": f.stem in reduced}
        t0 = time.perf_counter()
        try:
            scene = load_scene(f, entry["overrides"])
            entry["title"] = scene.title
            entry["reproduces"] = scene.reproduces
            if progress:
                print(f"gallery: {f.stem} ...", flush=True)
            summary = run_scene(scene, out / f.stem, workers=workers, progress=progress)
            s = json.loads((out / f.stem / "summary.json").read_text())
            entry["status"] = "ok"
            entry["headlines"] = s.get("headlines", [])
            entry["files"] = [x for x in s.get("files", []) if x.endswith(".png")]
            entry["points"] = summary.get("points_total")
            entry["points_failed"] = s.get("points_failed", 0)
        except (SceneError, SimulationError) as e:
            entry["status"] = "failed"
            entry["error"] = " ".join(str(e).split())
        except Exception as e:  # one broken scene must not hide the others
            entry["status"] = "failed"
            entry["error"] = f"{type(e).__name__}: {e}"
            entry["traceback"] = traceback.format_exc()
        entry["wall_time_s"] = time.perf_counter() - t0
        entries.append(entry)
    result = {"scenarios": str(scenarios), "quick": quick, "scenes": entries,
              "wall_time_s": time.perf_counter() - t_all,
              "failed": [e["scene"] for e in entries if e["status"] != "ok"]}
    from .results import write_json_atomic, write_text_atomic

    write_json_atomic(out / "gallery.json", _clean(result))
    write_text_atomic(out / "index.md", index_markdown(result))
    return result


def _clean(x):
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: _clean(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_clean(v) for v in x]
    return x


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
                lines.append(f"| {_fmt(h.get('quantity'))} | {_fmt(h.get('paper'))} | {_fmt(h.get('ours'))} | "
                             f"{_fmt(h.get('unit') or '')} | {_fmt(h.get('tolerance'))} | {_fmt(h.get('note') or '')} |")
        for png in e.get("files", []):
            lines += ["", f"![{png}]({e['scene']}/{png})"]
    return "\n".join(lines) + "\n"
