"""The headline registry: the papers' numbers beside ours, per scene.

A module registers ``f(scene, summary, results) -> list[dict]`` for the
scene files it knows (by file stem). Each dict has ``quantity``,
``paper`` (the paper's number or text), ``ours`` (a number or text),
``unit`` and optionally ``tolerance`` and ``note``. The report writes them
into summary.json; the gallery shows them side by side.
"""

from __future__ import annotations

from typing import Callable

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


def headlines_for(scene, summary: dict, results: list[dict]) -> list[dict]:
    func = HEADLINES.get(scene.path.stem)
    if func is None:
        return []
    try:
        return func(scene, summary, results)
    except (KeyError, IndexError, TypeError, ValueError) as e:
        return [{"quantity": "headline", "paper": None, "ours": None, "note": f"not computed: {e}"}]
