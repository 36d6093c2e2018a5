"""Headlines: the papers' numbers beside ours, per scene. ``registry`` holds
them by scene; ``ziemkiewicz``, ``chaos``, ``hoyng`` and ``environment`` (the scenes with air) define them.
Importing this package registers every scene's headlines."""

from . import chaos, environment, hoyng, ziemkiewicz  # noqa: F401  (each registers its scenes)
from .registry import HEADLINES, headline, headlines_for

__all__ = ["HEADLINES", "headline", "headlines_for"]
