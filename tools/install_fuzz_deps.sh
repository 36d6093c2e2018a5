#!/usr/bin/env bash
# Make sure clang with libFuzzer is available for tools/fuzz.sh; install it
# from the distribution (Debian/Ubuntu: clang and libclang-rt-dev) when not.
# Safe to run repeatedly; does nothing when a working clang is found.
set -euo pipefail

probe() {
  local cc
  cc=$(command -v clang || ls /usr/bin/clang-[0-9]* 2>/dev/null | sort -V | tail -n 1 || true)
  [ -n "$cc" ] || return 1
  local tmp
  tmp=$(mktemp -d)
  printf 'int LLVMFuzzerTestOneInput(const unsigned char *d, unsigned long n) { return 0; }\n' > "$tmp/probe.c"
  "$cc" -fsanitize=fuzzer,address,undefined "$tmp/probe.c" -o "$tmp/probe" > /dev/null 2>&1
  local rc=$?
  rm -rf "$tmp"
  return $rc
}

if probe; then exit 0; fi

SUDO=
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo > /dev/null; then SUDO=sudo; else
    echo "install_fuzz_deps: clang with libFuzzer is missing and I am not root; install clang and libclang-rt-dev" >&2
    exit 1
  fi
fi
if ! command -v apt-get > /dev/null; then
  echo "install_fuzz_deps: no apt-get here; install clang with libFuzzer (compiler-rt) yourself" >&2
  exit 1
fi
export DEBIAN_FRONTEND=noninteractive
install() { $SUDO apt-get install -y --no-install-recommends "$@" > /dev/null; }
# libclang-rt-dev holds libFuzzer on Debian 12 / Ubuntu 23.04 and later;
# before that the clang package brings it along.
install clang libclang-rt-dev || { $SUDO apt-get update > /dev/null && install clang libclang-rt-dev; } \
  || install clang || true
if ! probe; then
  echo "install_fuzz_deps: clang cannot build a libFuzzer binary even after installing clang" >&2
  exit 1
fi
echo "install_fuzz_deps: $(clang --version | head -n 1)"
