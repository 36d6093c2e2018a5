#!/usr/bin/env bash
# Install the project and build the FMUs into fmus/. Safe to run repeatedly.
# Packages go into the active virtual environment, else into the checkout's
# .venv (created when missing; tools/python.sh), never into the system's Python.
set -euo pipefail
cd "$(dirname "$0")/.."
source tools/python.sh
PY=$PYTHON
"$PY" -m pip install --quiet --disable-pip-version-check -e ".[test,interop,docs,parquet]"
# Bytecode, as pip writes it for an installed wheel: an editable install
# leaves it to the first import, which never writes it where
# PYTHONDONTWRITEBYTECODE is set, and every start-up then compiles the package.
"$PY" -m compileall -q clockwork > /dev/null
# ecospy's native library links against oneTBB (Debian: libtbb12).
libs=$(ldconfig -p 2>/dev/null || /sbin/ldconfig -p 2>/dev/null || true)
if ! grep -q 'libtbb\.so\.12' <<< "$libs"; then
  if [ "$(id -u)" -eq 0 ] && command -v apt-get > /dev/null; then
    { apt-get update -qq && apt-get install -y -qq libtbb12 > /dev/null; } ||
      echo "setup: apt-get could not install libtbb12: ecos cannot run"
  else
    echo "setup: libtbb12 is missing and this is not root: install it (apt-get install libtbb12), else ecos cannot run (tests/interop skip it outside CI)"
  fi
fi
cmake -S . -B build -G Ninja -DPython3_EXECUTABLE="$(command -v "$PY")" > build.log 2>&1 || { cat build.log; exit 1; }
cmake --build build >> build.log 2>&1 || { cat build.log; exit 1; }
rm -f build.log
echo "setup: FMUs in $(pwd)/fmus: $(ls fmus | tr '\n' ' ')"
echo "setup: Python packages in $("$PY" -c 'import sys; print(sys.prefix)')"
