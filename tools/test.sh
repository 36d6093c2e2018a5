#!/usr/bin/env bash
# Set everything up, then run all tests: the FMU suite through ctest, then
# everything else through pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
source tools/python.sh
bash tools/setup.sh
ctest --test-dir build --output-on-failure

# Hardening: the FMUs built with -fsanitize=address,undefined in build-asan/;
# ctest runs their C drivers (LeakSanitizer on) and the pytest FMU suite with
# the ASan runtime preloaded into Python. Then a bounded libFuzzer run of
# every FMU (a long one: bash tools/fuzz.sh --long). See docs/reliability.md.
mkdir -p build-asan
{ cmake -S . -B build-asan -G Ninja -DCW_SANITIZE=ON -DCW_FMU_DIR="$PWD/build-asan/fmus" \
    -DPython3_EXECUTABLE="$PYTHON" && cmake --build build-asan; } \
  > build-asan/build.log 2>&1 || { cat build-asan/build.log; exit 1; }
ctest --test-dir build-asan --output-on-failure
bash tools/install_fuzz_deps.sh
bash tools/fuzz.sh --fresh
set +e
# One pytest-xdist worker per core (CW_TEST_WORKERS to choose; 0: in this
# process), each test module on one worker: module fixtures run once, and
# each worker has its own temporary folders and cache (tests/conftest.py).
# Tests marked serial (signals sent after a fixed wait, bounds on how soon a
# run ends) run alone afterwards, in this process.
"$PYTHON" -m pytest tests --ignore=tests/fmu -q -n "${CW_TEST_WORKERS:-auto}" --dist loadscope -m "not serial" "$@"
rc=$?
"$PYTHON" -m pytest tests --ignore=tests/fmu -q -p no:xdist -m serial "$@"
rc_serial=$?
set -e
# 5: a pass that collected no tests (say, a -k that picks none of its kind).
[ "$rc" -eq 5 ] && rc=0
[ "$rc_serial" -eq 5 ] && rc_serial=0
[ "$rc" -ne 0 ] && exit "$rc"
exit "$rc_serial"
