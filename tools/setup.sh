#!/usr/bin/env bash
# Install the project and build the FMUs into fmus/. Safe to run repeatedly.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
"$PY" -m pip install --quiet --disable-pip-version-check -e ".[test]"
cmake -S . -B build -G Ninja -DPython3_EXECUTABLE="$(command -v "$PY")" > build.log 2>&1 || { cat build.log; exit 1; }
cmake --build build >> build.log 2>&1 || { cat build.log; exit 1; }
rm -f build.log
echo "setup: FMUs in $(pwd)/fmus: $(ls fmus | tr '\n' ' ')"
