#!/usr/bin/env bash
# Install the project and build the FMUs into fmus/. Safe to run repeatedly.
# Packages go into the active virtual environment, else into the checkout's
# .venv (created when missing; tools/python.sh), never into the system's Python.
set -euo pipefail
cd "$(dirname "$0")/.."
source tools/python.sh
PY=$PYTHON
# Debian packages, each only when missing, with one apt-get update: ecospy's
# native library links against oneTBB (libtbb12); mingw-w64 cross-compiles
# the FMUs' Windows DLLs (cmake/platforms.cmake) and wine runs them in
# tests/test_platforms.py (docs/other-tools.md, Platforms); Debian's Arm
# cross compiler builds the FMI 3.0 FMUs' aarch64-linux binaries and
# qemu-user runs them there.
libs=$(ldconfig -p 2>/dev/null || /sbin/ldconfig -p 2>/dev/null || true)
debs=()
grep -q 'libtbb\.so\.12' <<< "$libs" || debs+=(libtbb12)
command -v x86_64-w64-mingw32-gcc > /dev/null || debs+=(mingw-w64)
command -v wine > /dev/null || debs+=(wine wine64)
command -v aarch64-linux-gnu-gcc > /dev/null || debs+=(gcc-aarch64-linux-gnu libc6-dev-arm64-cross)
command -v qemu-aarch64 > /dev/null || debs+=(qemu-user)
if [ ${#debs[@]} -gt 0 ]; then
  if [ "$(id -u)" -eq 0 ] && command -v apt-get > /dev/null; then
    { apt-get update -qq &&
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${debs[@]}" > /dev/null; } ||
      echo "setup: apt-get could not install ${debs[*]}: without libtbb12 ecos cannot run, without mingw-w64 (gcc-aarch64-linux-gnu) the FMUs get no Windows (aarch64-linux) binaries, without wine (qemu-user) these are not tested"
  else
    echo "setup: ${debs[*]} missing and this is not root: install them (apt-get install ${debs[*]}), else ecos cannot run (libtbb12), the FMUs get no Windows or aarch64-linux binaries (mingw-w64, gcc-aarch64-linux-gnu) or these are not tested (wine, qemu-user); tests skip what is missing outside CI"
  fi
fi
"$PY" -m pip install --quiet --disable-pip-version-check -e ".[test,interop,docs,parquet]"
# Bytecode, as pip writes it for an installed wheel: an editable install
# leaves it to the first import, which never writes it where
# PYTHONDONTWRITEBYTECODE is set, and every start-up then compiles the package.
"$PY" -m compileall -q clockwork > /dev/null
cmake -S . -B build -G Ninja -DPython3_EXECUTABLE="$(command -v "$PY")" > build.log 2>&1 || { cat build.log; exit 1; }
cmake --build build >> build.log 2>&1 || { cat build.log; exit 1; }
rm -f build.log
echo "setup: FMUs in $(pwd)/fmus: $(ls fmus | tr '\n' ' ')"
echo "setup: Python packages in $("$PY" -c 'import sys; print(sys.prefix)')"
