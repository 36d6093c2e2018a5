"""python -m clockwork"""

from .cli import main

raise SystemExit(main())
