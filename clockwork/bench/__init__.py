"""The work-precision benchmark behind ``clockwork bench`` (docs/benchmarks.md).

``config``: families, steps, tolerances, rows; ``problems``: the problems
and their reference solutions; ``checks``: the reference checked first;
``masters`` and ``peers``: rows of clockwork (and scipy) and of other
tools (``peer_tool`` runs one in its own process); ``suites``: each
problem across its rows; ``targets`` and ``report``: the verdicts and the
files; ``run``: the whole benchmark.
"""

from .checks import reference_checks
from .config import DEFAULT_FAMILY, PEER_MODULES, RUN_TOOL, TWO_PI, BenchConfig, Family, Row, full_config, grid, quick_config
from .peers import PeerRunner, run_peer, tick_times, tool_available
from .problems import steady_point
from .report import CSV_FIELDS
from .run import run_bench

__all__ = ["BenchConfig", "CSV_FIELDS", "DEFAULT_FAMILY", "Family", "PEER_MODULES", "PeerRunner", "RUN_TOOL",
           "Row", "TWO_PI", "full_config", "grid", "quick_config", "reference_checks", "run_bench", "run_peer", "steady_point", "tick_times",
           "tool_available"]
