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

import time
import traceback
from pathlib import Path

from ..errors import SceneError, SimulationError, UsageError
from ..numbers import parse_json
from ..paths import scenarios_dir
from ..results.files import clean_json, write_json_atomic, write_text_atomic
from ..results.gallery import index_markdown
from .catalog import load_scene
from .scene_run import run_scene


def quick_overrides(scenarios: Path) -> dict[str, list[str]]:
    f = scenarios / "quick.json"
    if not f.is_file():
        return {}
    try:
        data = parse_json(f.read_bytes())
    except (OSError, ValueError) as e:
        raise SceneError(f"not strict JSON: {getattr(e, 'strerror', None) or e}", f) from None
    if not isinstance(data, dict):
        raise SceneError('expected {"scene_stem": ["key=value", ...]}', f)
    data = {k: v for k, v in data.items() if not k.startswith("_")}  # "_comment" and the like
    for k, v in data.items():
        if not (isinstance(v, list) and all(isinstance(x, str) for x in v)):
            raise SceneError('expected a list of "key=value" strings', f, k)
    return {k: list(v) for k, v in data.items()}


def run_gallery(out: Path, scenarios: Path | None = None, quick: bool = False, only: list[str] | None = None,
                workers: int | None = None, progress: bool = True, bars: bool | None = None) -> dict:
    """Run every scene (or `only` these stems) into out/<stem>/ and write the
    index. `progress`: a line per scene; `bars`: the runs' progress bars
    (default: as `progress`)."""
    out = Path(out)
    scenarios = Path(scenarios) if scenarios else scenarios_dir()
    out.mkdir(parents=True, exist_ok=True)
    files = sorted(scenarios.glob("*.toml"))
    if only:
        unknown = sorted(set(only) - {f.stem for f in files})
        if unknown:
            raise UsageError(f"--only {' '.join(unknown)}: no such scene in {scenarios} "
                             f"(scenes: {', '.join(f.stem for f in files)})")
        files = [f for f in files if f.stem in only]
    reduced = quick_overrides(scenarios) if quick else {}
    entries = []
    t_all = time.perf_counter()
    for f in files:
        entry = {"scene": f.stem, "file": str(f), "overrides": reduced.get(f.stem, []),
                 "quick": f.stem in reduced}
        t0 = time.perf_counter()
        try:
            scene = load_scene(f, entry["overrides"], streamed=True)
            entry["title"] = scene.title
            entry["reproduces"] = scene.reproduces
            if progress:
                print(f"gallery: {f.stem} ...", flush=True)
            summary = run_scene(scene, out / f.stem, workers=workers, progress=progress if bars is None else bars)
            s = parse_json((out / f.stem / "summary.json").read_bytes())
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
    write_json_atomic(out / "gallery.json", clean_json(result))
    write_text_atomic(out / "index.md", index_markdown(result))
    return result
