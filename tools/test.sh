#!/usr/bin/env bash
# Set everything up, then run all tests: the FMU suite through ctest, then
# everything else through pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
ctest --test-dir build --output-on-failure

# Hardening: the FMUs built with -fsanitize=address,undefined in build-asan/;
# ctest runs their C drivers (LeakSanitizer on) and the pytest FMU suite with
# the ASan runtime preloaded into Python. Then a bounded libFuzzer run of
# every FMU (a long one: bash tools/fuzz.sh --long). See docs/reliability.md.
mkdir -p build-asan
{ cmake -S . -B build-asan -G Ninja -DCW_SANITIZE=ON -DCW_FMU_DIR="$PWD/build-asan/fmus" \
    -DPython3_EXECUTABLE="$(command -v "${PYTHON:-python3}")" && cmake --build build-asan; } \
  > build-asan/build.log 2>&1 || { cat build-asan/build.log; exit 1; }
ctest --test-dir build-asan --output-on-failure
bash tools/install_fuzz_deps.sh
bash tools/fuzz.sh --fresh
set +e
"${PYTHON:-python3}" -m pytest tests --ignore=tests/fmu -q "$@"
rc=$?
set -e
if [ "$rc" -eq 5 ]; then
  echo "pytest collected no tests"
  rc=0
fi
exit "$rc"
