#!/usr/bin/env bash
# Set everything up, then run the main job: Ziemkiewicz Fig. 4(a), the
# grasshopper clock's steady-state rate errors over 24 driving torques.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
clockwork run scenarios/ziemkiewicz_fig4a.toml --out out/ziemkiewicz_fig4a
echo "main: results in out/ziemkiewicz_fig4a (summary.json, sweep.csv, PNG plots)"
