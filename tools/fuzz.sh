#!/usr/bin/env bash
# Build the libFuzzer harnesses fuzz/fuzz_fmu.c (FMI 2.0 face) and
# fuzz/fuzz_fmu3.c (FMI 3.0 face) against every model and run them.
#
#   bash tools/fuzz.sh                 bounded run (CI): 20000 executions per model (FMI 3.0: 5000)
#   bash tools/fuzz.sh --long          long run: 600 s per model
#   bash tools/fuzz.sh --time 3600     long run of that many seconds per model
#   bash tools/fuzz.sh --runs N --model Pendulum [--model Drag ...]
#   bash tools/fuzz.sh --fresh         start from the seeds only (CI: same work every run)
#
# Builds into build-fuzz/ (or $CW_FUZZ_DIR); the corpus grows in
# build-fuzz/corpus/<Model>/, starting from fuzz/seeds/ (kept across runs, so
# long runs build on earlier ones). A crash, sanitizer report, broken
# invariant or timeout leaves its input in build-fuzz/crash-<Model>[_fmi3]-* and
# fails the script; rerun one with  build-fuzz/fuzz_<Model>[_fmi3] FILE.
# Needs clang with libFuzzer: tools/install_fuzz_deps.sh.
set -euo pipefail
cd "$(dirname "$0")/.."

RUNS=20000
TIME=0
MODELS=()
FRESH=0
OUT=${CW_FUZZ_DIR:-build-fuzz}
while [ $# -gt 0 ]; do
  case "$1" in
    --runs) RUNS=$2; shift 2 ;;
    --time) TIME=$2; RUNS=-1; shift 2 ;;
    --long) TIME=600; RUNS=-1; shift ;;
    --model) MODELS+=("$2"); shift 2 ;;
    --fresh) FRESH=1; shift ;;
    --out) OUT=$2; shift 2 ;;
    *) echo "fuzz.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done

CC=${CW_FUZZ_CC:-}
if [ -z "$CC" ]; then
  CC=$(command -v clang || ls /usr/bin/clang-[0-9]* 2>/dev/null | sort -V | tail -n 1 || true)
fi
if [ -z "$CC" ]; then
  echo "fuzz.sh: no clang found; run tools/install_fuzz_deps.sh" >&2
  exit 1
fi
PY=${PYTHON:-python3}
FMI=$("$PY" -c "import fmpy, os; print(os.path.join(os.path.dirname(fmpy.__file__), 'c-code'))")
if [ ${#MODELS[@]} -eq 0 ]; then
  for t in src_c/models/*/model.toml; do MODELS+=("$(basename "$(dirname "$t")")"); done
  # The test FMU with String variables (FMI 2.0 only): the runtime's String storage.
  MODELS+=(TestTypes)
fi
# A model's folder: src_c/models, else tests/models (FMI 2.0 builds only).
model_dir() { if [ -d "src_c/models/$1" ]; then echo "src_c/models/$1"; else echo "tests/models/$1"; fi; }

# The integrators' per-call step limit is lowered so that a fuzzed step of
# 1e9 s with a 1e-9 s step cap is discarded after 20000 internal steps
# instead of 1e6: the same code path, at fuzzing speed.
FLAGS=(-std=c99 -g -O1 -fno-omit-frame-pointer
       -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all
       -DCW_RK_MAX_STEPS=20000 -Wall -Wno-unused-parameter)
mkdir -p "$OUT"
summary="$OUT/summary.txt"
: > "$summary"
failed=0
total=0
# Each model is fuzzed through both faces of the runtime: fuzz_fmu.c drives
# the fmi2 functions (and through them the shared core), fuzz_fmu3.c what the
# fmi3 face adds (Event Mode, early return, typed access, its states). The
# FMI 3.0 harness gets a quarter of the bounded runs: the core under it is
# the one the FMI 2.0 harness already covers.
fuzz_one() {
  local m=$1 face=$2 runs=$3
  local gen="$OUT/gen/$m" name="$m" harness=fuzz/fuzz_fmu.c
  [ "$face" = 3 ] && name="${m}_fmi3" && harness=fuzz/fuzz_fmu3.c
  "$CC" "${FLAGS[@]}" -I"$gen" -Isrc_c/runtime -I"$FMI" -Itests/c \
        "$harness" "src_c/runtime/cw_fmi$face.c" "$OUT/obj/$m"/*.o -lm -o "$OUT/fuzz_$name"
  local corpus="$OUT/corpus/$name"
  [ "$FRESH" -eq 1 ] && rm -rf "$corpus"
  mkdir -p "$corpus"
  local seeds=()
  [ -d "fuzz/seeds/$m" ] && [ "$face" = 2 ] && seeds+=("fuzz/seeds/$m")
  [ -d fuzz/seeds/common ] && seeds+=(fuzz/seeds/common)
  local log="$OUT/fuzz_$name.log"
  local args=(-seed=1 -timeout=20 -max_len=4096 -rss_limit_mb=2048 -print_final_stats=1
              -artifact_prefix="$OUT/crash-$name-")
  # Long runs let the input length (the length of the call sequences) grow
  # faster than libFuzzer's default.
  if [ "$runs" -ge 0 ]; then args+=(-runs="$runs"); else args+=(-max_total_time="$TIME" -len_control=20); fi
  local start rc secs execs cov result line
  start=$(date +%s)
  set +e
  "$OUT/fuzz_$name" "${args[@]}" "$corpus" "${seeds[@]}" > "$log" 2>&1
  rc=$?
  set -e
  secs=$(( $(date +%s) - start ))
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -n 1)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -n 1 | cut -d' ' -f2)
  execs=${execs:-0}
  total=$(( total + execs ))
  if [ "$rc" -eq 0 ]; then result=ok; else result="FAILED (exit $rc, see $log)"; failed=1; fi
  line="$name: $execs executions in ${secs} s, coverage ${cov:-?} edges, corpus $(ls "$corpus" | wc -l) inputs: $result"
  echo "fuzz: $line"
  echo "$line" >> "$summary"
  if [ "$rc" -ne 0 ]; then grep -E "ERROR|FAIL|fuzz_fmu|SUMMARY|runtime error" "$log" | head -n 20 >&2 || true; fi
}

for m in "${MODELS[@]}"; do
  dir=$(model_dir "$m")
  only=()
  [ "$dir" = "tests/models/$m" ] && only=(--fmi2-only)
  "$PY" tools/fmugen.py "$dir" "$OUT/gen/$m" --sources cw_runtime.c cw_fmi2.c cw_rk.c model.c "${only[@]}" > /dev/null
  # The core, the integrators and the model, compiled once for both harnesses.
  rm -rf "$OUT/obj/$m" && mkdir -p "$OUT/obj/$m"
  for src in src_c/runtime/cw_runtime.c src_c/runtime/cw_rk.c "$dir/model.c"; do
    "$CC" "${FLAGS[@]}" -c -I"$OUT/gen/$m" -Isrc_c/runtime -I"$FMI" "$src" \
          -o "$OUT/obj/$m/$(basename "$src" .c).o"
  done
  fuzz_one "$m" 2 "$RUNS"
  [ ${#only[@]} -gt 0 ] && continue
  if [ "$RUNS" -ge 0 ]; then fuzz_one "$m" 3 $(( RUNS / 4 )); else fuzz_one "$m" 3 -1; fi
done
echo "fuzz: $total executions in total" | tee -a "$summary"
exit "$failed"
