#!/usr/bin/env bash
# Coverage-guided fuzzing of the parsers of outside data (issue 21): builds the libFuzzer
# targets of fuzz/ on the stable toolchain, writes the seed corpora from the repository's
# real files, runs each target and prints, per target, executions, corpus size and crashes.
#
#   tools/fuzz.sh [--seconds N] [--parallel P] [--opt-level L] [--keep-going] [--no-seeds]
#                 [--build-only] [TARGET...]
#
# --seconds N     run time per target (default 60)
# --parallel P    targets run at once (default 1)
# --opt-level L   the targets' optimisation level (default fuzz/Cargo.toml's, 3; CI's
#                 short runs take 1, a build 18 % shorter)
# --keep-going    libFuzzer's fork mode, which records a crash and goes on (long runs)
# --no-seeds      the corpus as it is (repeated runs)
# --build-only    build the targets and stop (CI builds them beside the tests, then runs
#                 them with the same --opt-level: the build is then already done)
# No TARGET: all of them. Exit status 1 if the build fails or any target crashed, hung
# (-timeout=10) or ran out of memory (-rss_limit_mb=2048).
# Corpora grow in fuzz/corpus/<target>/ (not committed); crashing inputs land in
# fuzz/artifacts/<target>/; save them under tests/fuzz_cases/<target>/ with a test in
# tests/suite/fuzz_regressions.rs. Logs: fuzz/logs/<target>.log.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=60
parallel=1
keep_going=0
seeds=1
build_only=0
opt_level=()
targets=()
while [ $# -gt 0 ]; do
  case "$1" in
    --seconds) seconds=$2; shift 2 ;;
    --parallel) parallel=$2; shift 2 ;;
    --opt-level) opt_level=(--config "profile.release.opt-level=$2"); shift 2 ;;
    --keep-going) keep_going=1; shift ;;
    --no-seeds) seeds=0; shift ;;
    --build-only) build_only=1; shift ;;
    -h|--help) sed -n 2,21p "$0"; exit 0 ;;
    *) targets+=("$1"); shift ;;
  esac
done
all=(station_yaml mesh mp4 h264_sample frame_image shape_library template_sidecar recording_layout)
[ ${#targets[@]} -gt 0 ] || targets=("${all[@]}")

# libFuzzer through the libfuzzer-sys crate on stable Rust: the coverage instrumentation
# cargo-fuzz asks of nightly, given as stable codegen flags (SanitizerCoverage with inline
# 8-bit counters, PC table and compare tracing); debug assertions and overflow checks on
# (fuzz/Cargo.toml). An explicit --target keeps the flags off build scripts and proc macros.
host=$(rustc -vV | sed -n 's/^host: //p')
export RUSTFLAGS="--cfg fuzzing -Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4 \
-Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table \
-Cllvm-args=-sanitizer-coverage-trace-compares"
echo "== building the fuzz targets (fuzz/target)"
cargo build --release "${opt_level[@]}" --manifest-path fuzz/Cargo.toml --target "$host" --bins
bin=fuzz/target/$host/release
[ "$build_only" = 0 ] || exit 0

if [ "$seeds" = 1 ]; then
echo "== seed corpora from the repository's files (fuzz/corpus, tests/fuzz_seeds.rs)"
# Built with the main crate's flags in target/ (CI has just built it for the tests).
mkdir -p fuzz/logs
if ! (unset RUSTFLAGS; FITSTATION_FUZZ_SEEDS="$PWD/fuzz/corpus" \
  cargo test --release --test fuzz_seeds -- --nocapture >fuzz/logs/seeds.log 2>&1); then
  cat fuzz/logs/seeds.log
  exit 1
fi
grep 'seeds written' fuzz/logs/seeds.log
fi

run_one() {
  local t=$1
  local mode=()
  [ "$keep_going" = 0 ] || mode=(-fork=1 -ignore_crashes=1 -ignore_timeouts=1 -ignore_ooms=1)
  mkdir -p "fuzz/corpus/$t" "fuzz/artifacts/$t" fuzz/logs "tests/fuzz_cases/$t"
  # New inputs go into the first folder; the saved crash cases are read as seeds too.
  nice -n 10 "$bin/$t" "fuzz/corpus/$t" "tests/fuzz_cases/$t" \
    -max_total_time="$seconds" -rss_limit_mb=2048 -timeout=10 -print_final_stats=1 \
    -artifact_prefix="fuzz/artifacts/$t/" "${mode[@]}" >"fuzz/logs/$t.log" 2>&1
}

status=0
pids=()
names=()
for t in "${targets[@]}"; do
  [ -x "$bin/$t" ] || { echo "no fuzz target '$t' (known: ${all[*]})"; exit 1; }
  # Old artifacts are not this run's crashes.
  rm -f fuzz/artifacts/"$t"/crash-* fuzz/artifacts/"$t"/timeout-* fuzz/artifacts/"$t"/oom-* \
    fuzz/artifacts/"$t"/leak-* fuzz/artifacts/"$t"/slow-unit-* 2>/dev/null || true
  echo "== fuzzing $t for ${seconds}s"
  run_one "$t" &
  pids+=($!)
  names+=("$t")
  if [ ${#pids[@]} -ge "$parallel" ]; then
    wait "${pids[0]}" || true
    pids=("${pids[@]:1}")
  fi
done
for p in "${pids[@]}"; do wait "$p" || true; done

printf '\n%-18s %8s %12s %8s %8s %8s\n' target seconds executions exec/s corpus crashes
for t in "${names[@]}"; do
  log=fuzz/logs/$t.log
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
  if [ -z "$execs" ]; then
    # Fork mode's status lines: "#EXECS: cov: .. corp: .. exec/s: NOW .. time: Ts" (the
    # average rate is executions over time).
    execs=$(sed -n 's/^#\([0-9]*\): cov:.*/\1/p' "$log" | tail -1)
    took=$(sed -n 's/^#[0-9]*: cov:.* time: \([0-9]*\)s.*/\1/p' "$log" | tail -1)
    [ -z "$execs" ] || [ -z "$took" ] || [ "$took" = 0 ] || rate=$((execs / took))
  fi
  corpus=$(find "fuzz/corpus/$t" -type f | wc -l)
  crashes=$(find "fuzz/artifacts/$t" -type f \( -name 'crash-*' -o -name 'timeout-*' \
    -o -name 'oom-*' -o -name 'leak-*' \) | wc -l)
  printf '%-18s %8s %12s %8s %8s %8s\n' "$t" "$seconds" "${execs:-?}" "${rate:-?}" "$corpus" "$crashes"
  if [ "$crashes" != 0 ] || [ -z "$execs" ]; then
    status=1
    echo "  $t: see $log and fuzz/artifacts/$t/" >&2
  fi
done
exit $status
