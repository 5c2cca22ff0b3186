#!/usr/bin/env bash
# Same behaviour, to the bit: runs the timing-free outputs of two builds (detection CSVs of real
# and simulated scans, the simulated scans themselves, the detection / drone / merge / map-build
# test figures, bench-mapping JSON and bench-reloc figures) and diffs them. For refactors that must
# not change a result (issue 12).
#
#   tests/bench/same_behaviour.sh BASE_BUILD NEW_BUILD [WORK_DIR]
#
# BASE_BUILD, NEW_BUILD: CMake build directories holding client/cli/forestmap and
# client/lab/forestmap-lab (or, built before the lab was apart, client/forestmap doing both) and
# the tests of tests/algorithms/**/{trunk_detection_sim_test,trunk_detection_real_data_test,
# drone_scan_pair_test,map_merge_test,map_builder_test}.cc (a program of that name, or the test
# program of its folder, run with a filter for the file's suites in both builds). Data from FORESTMAP_SHARED_DATA (default ../shared/data).
# FORESTMAP_SAME_QUICK=1 skips the slow runs (the 120-pose detection test, bench-mapping without
# poses). Exits 0 when every output is identical, 1 on any difference, 2 on a usage error.
set -uo pipefail

if [[ $# -lt 2 ]]; then
  echo "usage: $0 BASE_BUILD NEW_BUILD [WORK_DIR]" >&2
  exit 2
fi
BASE=$(realpath "$1")
NEW=$(realpath "$2")
WORK=${3:-$(mktemp -d /tmp/same_behaviour.XXXXXX)}
DATA=$(realpath "${FORESTMAP_SHARED_DATA:-../shared/data}")
QUICK=${FORESTMAP_SAME_QUICK:-0}
# cli_of BUILD / lab_of BUILD: the program running the user's commands / the lab's commands.
cli_of() {
  if [[ -x $1/client/cli/forestmap ]]; then echo "$1/client/cli/forestmap"; else echo "$1/client/forestmap"; fi
}
lab_of() {
  if [[ -x $1/client/lab/forestmap-lab ]]; then echo "$1/client/lab/forestmap-lab"; else echo "$1/client/forestmap"; fi
}
for b in "$BASE" "$NEW"; do
  for program in "$(cli_of "$b")" "$(lab_of "$b")"; do
    if [[ ! -x $program ]]; then
      echo "error: $program not found (build the forestmap and forestmap-lab targets)" >&2
      exit 2
    fi
  done
done
if [[ ! -d $DATA/scans ]]; then
  echo "error: no shared data at $DATA (set FORESTMAP_SHARED_DATA)" >&2
  exit 2
fi
mkdir -p "$WORK/base" "$WORK/new"
S=$DATA/stemmaps
Q=$DATA/sequences
SC=$DATA/scans
failed=0

# Drops what depends on the clock or the machine: gtest times "(12 ms)", JSON fields and text
# figures ("key: value") of seconds, milliseconds, rates, throughput and resident memory.
# One-line JSON objects are spread one field a line first, so that the timing fields drop alone.
spread_json() {
  python3 -c '
import json, sys
for line in sys.stdin:
    try:
        print(json.dumps(json.loads(line), indent=2, sort_keys=True))
    except ValueError:
        sys.stdout.write(line)
'
}

strip_timing() {
  spread_json | sed -E \
    -e 's/ \([0-9]+ ms( total)?\)//g' \
    -e '/"[A-Za-z0-9_]*(seconds|_s|_ms|_us|ms_|time|latency|per_second|fps|throughput|rate_hz|resident|rss)[A-Za-z0-9_]*" *:/d' \
    -e '/^ *[A-Za-z0-9_]*(seconds|_s|_ms|_us|ms_|time|latency|per_second|fps|throughput|rate_hz|resident|rss)[A-Za-z0-9_]*:/d' \
    -e 's/; ms: .*$//' \
    -e 's/(\.cc):[0-9]+: Failure/\1:<line>: Failure/' \
    -e 's#^[./]*(tests/)?([a-z_]+/)*([a-z_]+\.cc:<line>: Failure)#\3#' \
    -e 's/[0-9]+([.][0-9]+)? *(ms|s|µs|us)( per [a-z]+)?\b/<t>/g' \
    -e 's/[0-9]+([.][0-9]+)? *(frames|scans|queries)\/s/<t>/g'
}

# test_program BUILD NAME: the test program NAME in BUILD or, one program a test folder, the
# program of the folder holding NAME.cc (tests/algorithms/merging -> algorithms_merging_tests).
SOURCE=$(realpath "$(dirname "$0")/../..")
test_program() {
  local program dir
  program=$(find "$1/tests" -type f -perm -u+x -name "$2" | head -1)
  if [[ -z $program ]]; then
    dir=$(dirname "$(find "$SOURCE/tests" -name "$2.cc" | head -1)")
    dir=${dir#"$SOURCE"/tests/}
    program=$(find "$1/tests/$dir" -maxdepth 1 -type f -perm -u+x -name "${dir//\//_}_tests")
  fi
  echo "$program"
}
# suite_filter NAME: a --gtest_filter of the test suites of NAME.cc.
suite_filter() {
  grep -hoE '^TEST(_F|_P)?\([A-Za-z0-9_]+,' $(find "$SOURCE/tests" -name "$1.cc") |
    sed -E 's/.*\(//; s/,$/.*/' | sort -u | paste -sd:
}

# run NAME CMD...: runs CMD with @B@ replaced by each build, @CLI@ and @LAB@ by its programs (and
# @OUT@ by that build's output directory), stores its timing-free stdout + stderr and compares
# them.
run() {
  local name=$1
  shift
  for side in base new; do
    local build=$BASE
    [[ $side == new ]] && build=$NEW
    local args=(env)
    for a in "$@"; do
      a=${a//@CLI@/$(cli_of "$build")}
      a=${a//@LAB@/$(lab_of "$build")}
      a=${a//@B@/$build}
      # @TEST@/NAME: the tests of NAME.cc in that build (test_program, suite_filter).
      if [[ $a == @TEST@/* ]]; then
        args+=("GTEST_FILTER=$(suite_filter "${a#@TEST@/}")")
        a=$(test_program "$build" "${a#@TEST@/}")
      fi
      a=${a//@OUT@/$WORK/$side}
      args+=("$a")
    done
    "${args[@]}" 2>&1 | strip_timing | sed "s#$WORK/$side#@OUT@#g" > "$WORK/$side/$name.txt"
    echo "exit ${PIPESTATUS[0]}" >> "$WORK/$side/$name.txt"
  done
  if cmp -s "$WORK/base/$name.txt" "$WORK/new/$name.txt"; then
    printf 'same       %s (%s lines)\n' "$name" "$(wc -l < "$WORK/new/$name.txt")"
  else
    printf 'DIFFERENT  %s\n' "$name"
    diff "$WORK/base/$name.txt" "$WORK/new/$name.txt" | head -20
    failed=1
  fi
}

# compare NAME FILE: a file both builds wrote into their output directory.
compare() {
  if cmp -s "$WORK/base/$2" "$WORK/new/$2"; then
    printf 'same       %s\n' "$1"
  else
    printf 'DIFFERENT  %s\n' "$1"
    failed=1
  fi
}

F=@CLI@ L=@LAB@
T=@TEST@

# Trunk detection on real scans (CSV: positions, DBH, diagnostics).
run detect_lidr "$F" detect "$SC/lidr_dbh_slice/dbh.las" --format json
run detect_sloam_tree_t0 "$F" detect "$SC/sloam_uav_ouster/still_tree_t0.pcd" --format json
run detect_sloam_moving_t1 "$F" detect "$SC/sloam_uav_ouster/moving_tree_t1.pcd" --format json
run detect_ponderosa_mls "$F" detect "$SC/spanner_ponderosa/MLS_Clip.pcd" --multi-view --format json
run detect_ponderosa_uas "$F" detect "$SC/spanner_ponderosa/UAS_Clip.pcd" --format json
run detect_treescope_43 "$F" detect "$SC/treescope_trunk_slices/tree_43_main_trunk.pcd" --multi-view --format json

# Simulated scans: the scans themselves (scan simulation), then detection on each.
run simulate_longleaf "$L" simulate --map "$S/spatstat_longleaf.csv" --random-poses 6 --scanner os1-64 \
  --seed 7 --out @OUT@/scans
for f in "$WORK"/new/scans/*; do
  [[ -f $f ]] && compare "simulated $(basename "$f")" "scans/$(basename "$f")"
done
for f in "$WORK"/new/scans/*.pcd; do
  [[ -f $f ]] || continue
  name=$(basename "$f" .pcd)
  run "detect_sim_$name" "$F" detect "@OUT@/scans/$name.pcd" --format json
done
run bench_reloc_scans "$L" bench-reloc --map @OUT@/scans/map.csv --scans @OUT@/scans

# Test figures (they print their tables; gtest times stripped).
if [[ $QUICK != 1 ]]; then
  run trunk_detection_sim_test env FORESTMAP_DETECT_POSES=120 "$T/trunk_detection_sim_test"
fi
run trunk_detection_real_data_test "$T/trunk_detection_real_data_test"
run drone_scan_pair_test "$T/drone_scan_pair_test"
run map_merge_test "$T/map_merge_test"
run map_builder_test "$T/map_builder_test"

# Merging and mapping (docs/performance.md "Shared maps and mapping"), timing fields stripped.
run bench_mapping_survey "$L" bench-mapping --frames "$Q/Wild_V01/trees.csv" --poses "$Q/Wild_V01/poses.csv" \
  --use-poses --map "$Q/Wild_V01/map.csv" --json
run bench_mapping_stein "$L" bench-mapping --frames "$Q/Oxford_Stein/trees.csv" \
  --poses "$Q/Oxford_Stein/poses.csv" --eval-frames "$Q/Oxford_Stein/trees.csv" \
  --eval-poses "$Q/Oxford_Stein/poses.csv" --json
if [[ $QUICK != 1 ]]; then
  run bench_mapping_wild "$L" bench-mapping --frames "$Q/Wild_V01/trees.csv" --poses "$Q/Wild_V01/poses.csv" \
    --eval-frames "$Q/Wild_V02/trees.csv" --eval-poses "$Q/Wild_V02/poses.csv" \
    --truth-offset 0.051,0.102,-0.039,-0.014 --json
fi

# Relocalization on simulated frames of the longleaf stem map.
run bench_reloc_longleaf "$L" bench-reloc --map "$S/spatstat_longleaf.csv" --simulate 200 --range 15

echo "outputs in $WORK"
if [[ $failed == 0 ]]; then
  echo "SAME: every output identical"
else
  echo "DIFFERENT: see above"
fi
exit $failed
