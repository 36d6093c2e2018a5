"""What the [analysis] and [[plot]] tables of a scene may hold.

The scene format names an analysis kind and plot kinds; what each kind
allows is defined by the layers that implement them (clockwork.analyses,
clockwork.results.plots), which hand their tables to ``load_scene`` as a
``Kinds``. A kind's converter gets its table without ``kind`` (only
allowed keys, raw TOML values), returns the converted values, and raises
``Invalid(key, expected)`` for a bad one.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Mapping

Converter = Callable[[dict], dict]


class Invalid(Exception):
    """Raised by a kind's converter: Invalid(key, 'what was expected')."""

    def __init__(self, key: str, expected: str):
        super().__init__(key, expected)
        self.key = key
        self.expected = expected


@dataclass(frozen=True)
class Kinds:
    analysis_keys: Mapping[str, set[str]] = field(default_factory=dict)  # kind -> allowed keys besides `kind`
    analysis_convert: Mapping[str, Converter] = field(default_factory=dict)
    plot_keys: Mapping[str, set[str]] = field(default_factory=dict)
    plot_convert: Mapping[str, Converter] = field(default_factory=dict)


NO_KINDS = Kinds()
