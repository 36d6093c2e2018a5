"""The headline registry: the papers' numbers beside ours, per scene.

A module registers ``f(scene, summary, results) -> list[dict]`` for the
scene files it knows (by file stem). Each dict has ``quantity``,
``paper`` (the paper's number or text), ``ours`` (a number or text),
``unit`` and optionally ``tolerance`` and ``note``. The report writes them
into summary.json; the gallery shows them side by side.
"""

from __future__ import annotations

from typing import Callable

from ...errors import ClockworkError

HEADLINES: dict[str, Callable] = {}


def headline(*scene_stems: str):
    def wrap(func):
        for stem in scene_stems:
            HEADLINES[stem] = func
        return func

    return wrap


def entry(quantity: str, paper, ours, unit: str = "", tolerance=None, note: str | None = None) -> dict:
    """One headline: a quantity, the paper's value (a number or text) beside ours."""
    d = {"quantity": quantity, "paper": paper, "ours": ours, "unit": unit}
    if tolerance is not None:
        d["tolerance"] = tolerance
    if note:
        d["note"] = note
    return d


def physical_overrides(scene) -> list[str]:
    """The --set arguments that change the clock or what is measured (a
    component's parameter, the experiment, the analysis), as opposed to
    the numerical method (master), the title or the recording."""
    return [o for o in scene.overrides if o.split("=", 1)[0].strip().split(".")[0] not in ("master", "scene", "record")]


def headlines_for(scene, summary: dict, results: list[dict]) -> list[dict]:
    """The scene's headlines. When --set changed what the paper's numbers
    depend on, every headline says so and is marked not comparable."""
    func = HEADLINES.get(scene.path.stem)
    if func is None:
        return []
    try:
        out = func(scene, summary, results)
    except (KeyError, IndexError, TypeError, ValueError, ClockworkError) as e:
        return [entry("headline", None, None, note=f"not computed: {' '.join(str(e).split())}")]
    changed = physical_overrides(scene)
    if changed:
        flag = ("scene run with --set " + ", ".join(changed)
                + ": the paper's value belongs to the scene as written, not to this run")
        for h in out:
            if h.get("paper") is not None:
                h["comparable"] = False
            h["note"] = f"{h['note']}; {flag}" if h.get("note") else flag
    return out
