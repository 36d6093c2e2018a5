#!/usr/bin/env bash
# Set everything up, then run the main job: Ziemkiewicz Fig. 4(a), the
# grasshopper clock's steady-state rate errors over 24 driving torques.
# Runs in the Python that setup installs into (tools/python.sh: the active
# venv, else the checkout's .venv). Finished points are reused from the
# user-wide cache (~/.cache/clockwork): CLOCKWORK_CACHE=off computes them all.
set -euo pipefail
cd "$(dirname "$0")/.."
source tools/python.sh
bash tools/setup.sh
"$PYTHON" -m clockwork run scenarios/ziemkiewicz_fig4a.toml --out out/ziemkiewicz_fig4a
echo "main: results in out/ziemkiewicz_fig4a (summary.json, sweep.csv, PNG plots)"
