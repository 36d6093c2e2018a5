"""python -m clockwork"""

from .cli import console

raise SystemExit(console())
