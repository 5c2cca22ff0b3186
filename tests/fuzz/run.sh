#!/usr/bin/env bash
# Runs every libFuzzer target of tests/fuzz for SECONDS each, starting from its seed corpus
# (tests/fuzz/corpus/<target>/, never written to: new inputs go to a scratch copy), JOBS targets
# at a time. Fails on any crash, leak, timeout or out-of-memory, printing the report and the
# input that caused it; otherwise prints "Fuzzing: N targets, M executions, 0 crashes".
# Usage: tests/fuzz/run.sh BUILD_DIR [SECONDS=30] [JOBS=1] [TARGET...]
#   FUZZ_OUT=DIR keeps logs, scratch corpora and crash inputs there (default: a temp dir).
#   FUZZ_NICE=N runs the fuzzers under nice -n N (default 0).
#   FUZZ_SEED=N fixes libFuzzer's random seed: the same mutations in the same order on every run,
#   so a short run (the test command's) finds the same inputs wherever it runs, and a failure is
#   reproducible. Unset (long exploratory runs): a new seed each run.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
build="$1"
seconds="${2:-30}"
jobs="${3:-1}"
shift $(($# < 3 ? $# : 3))
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(fuzz_tree_csv fuzz_pcd fuzz_ply fuzz_las fuzz_text_scan fuzz_validation \
  fuzz_http_routes fuzz_metrics)
out="${FUZZ_OUT:-$(mktemp -d /tmp/forestmap-fuzz.XXXXXX)}"
mkdir -p "$out"

run_one() {  # target -> out/target.{log,rc}
  local t="$1" bin="$build/tests/fuzz/$1"
  [ -x "$bin" ] || { echo "missing $bin (build target fuzz_targets)" >"$out/$t.log"; echo 1 >"$out/$t.rc"; return; }
  mkdir -p "$out/corpus/$t"
  local rc=0 TIMEFORMAT='%U %S'
  # -timeout: one input taking over 25 s is a hang; -rss_limit_mb: libFuzzer's default, stated.
  # The CPU seconds (user + system) go to target.cpu: on a shared machine they are below wall time.
  { time nice -n "${FUZZ_NICE:-0}" "$bin" -max_total_time="$seconds" -timeout=25 \
    -rss_limit_mb=2048 ${FUZZ_SEED:+-seed="$FUZZ_SEED"} -print_final_stats=1 -artifact_prefix="$out/$t-" "$out/corpus/$t" \
    "$here/corpus/$t" >"$out/$t.log" 2>&1 || rc=$?; } 2>"$out/$t.cpu"
  echo "$rc" >"$out/$t.rc"
}
export -f run_one
export build seconds out here
printf '%s\n' "${targets[@]}" | xargs -P "$jobs" -I{} bash -c 'run_one "$@"' _ {}

total=0 crashes=0
for t in "${targets[@]}"; do
  rc="$(cat "$out/$t.rc")"
  runs="$(sed -n 's/^stat::number_of_executed_units: *//p' "$out/$t.log" | tail -1)"
  runs="${runs:-0}"
  secs="$(sed -n 's/^Done [0-9]* runs in \([0-9]*\) second.*/\1/p' "$out/$t.log" | tail -1)"
  cpu="$(awk '{printf "%.0f", $1 + $2}' "$out/$t.cpu" 2>/dev/null || true)"
  total=$((total + runs))
  if [ "$rc" -ne 0 ]; then
    crashes=$((crashes + 1))
    echo "FUZZ CRASH in $t (exit $rc) after $runs executions; report:"
    # From the sanitizer's or libFuzzer's first report line on (progress lines are noise).
    report="$(awk '/ERROR:|runtime error|DEADLYSIGNAL|deadly signal|Timeout|out-of-memory|uncaught/ {p=1} p' \
      "$out/$t.log" | grep -v '^#[0-9]' | head -60 || true)"
    [ -n "$report" ] || report="$(tail -20 "$out/$t.log")"
    echo "$report"
    ls "$out/$t"-* 2>/dev/null | sed 's/^/  input: /' || true
  else
    echo "fuzz: $t: $runs executions in ${secs:-$seconds} s (${cpu:-?} s CPU), 0 crashes"
  fi
done
echo "Fuzzing: ${#targets[@]} targets, $total executions, $crashes crashes (logs in $out)"
[ "$crashes" -eq 0 ]
