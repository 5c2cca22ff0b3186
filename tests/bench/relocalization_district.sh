#!/usr/bin/env bash
# Relocalization across a forest district (docs/performance.md), measured on this machine:
#   tests/bench/relocalization_district.sh [--quick]   (after ./deploy/build.sh; --quick: 200
#                                                       views, a 200,000-tree mosaic, 50 views
#                                                       per foreign pair; FORESTMAP_BIN: the
#                                                       forestmap-lab binary to measure)
# Prints one markdown row per case. Latency: wall time per query in one thread (p95 of all
# answers) and CPU time (a busy machine inflates the wall time).
set -euo pipefail
cd "$(dirname "$0")/../.."
F=${FORESTMAP_BIN:-build/client/lab/forestmap-lab} D=${FORESTMAP_SHARED_DATA:-../shared/data}/sequences
S=${FORESTMAP_SHARED_DATA:-../shared/data}/stemmaps
VIEWS=1000 MOSAIC=1000000 PLANT=200 PAIR=100
if [ "${1:-}" = "--quick" ]; then VIEWS=200 MOSAIC=200000 PLANT=100 PAIR=50; fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

row() {  # row NAME bench-reloc-arguments...
  local name=$1; shift
  "$F" bench-reloc "$@" --json --per-frame "$tmp/frames.csv" 2>/dev/null | python3 -c '
import csv, json, sys
r = json.load(sys.stdin)
cpu = sorted(float(x["cpu_ms"]) for x in csv.DictReader(open(sys.argv[2])))
p95 = cpu[min(len(cpu) - 1, int(0.95 * len(cpu)))] if cpu else 0
rec = "-" if r["foreign_map"] else "%.1f%%" % (100 * r["recall"])
print("| %s | %d | %s | %d (%d loc., %d amb., %d n.f.) | %.2f / %.2f ms | %.2f ms | %s | %.0f B/tree |" % (
    sys.argv[1], r["frames"], rec, r["wrong"], r["localized"], r["ambiguous"], r["not_found"],
    r["time_p50_ms"], r["time_p95_ms"], p95,
    "%.2f" % r["nees_xy_yaw_mean"] if r["localized"] and not r["foreign_map"] else "-",
    r["index_resident_bytes_per_tree"]))
' "$name" "$tmp/frames.csv"
}

echo "| case | views | recall | wrong (outcomes) | wall p50 / p95 | CPU p95 | mean NEES (3 dof) | index |"
echo "|---|---|---|---|---|---|---|---|"
MAPS=$S/siplab_boreasNS.csv,$S/spatstat_longleaf.csv,$S/spatstat_urkiola.csv,$S/spatstat_waka.csv,$S/ads_Allogny.csv,$S/ads_BPoirier.csv
for seed in 1 2 3; do
  row "mosaic of 6 stem maps, $MOSAIC trees, seed $seed" --mosaic $MAPS --mosaic-trees $MOSAIC \
    --simulate $VIEWS --range 15 --seed $seed
done
for design in 3,2.5,0.3,0.15 3,3,0.5,0.3 4,4,0.5,0.25 4,4,0.2,0.1 5,5,0.2,0.05; do
  for seed in 1 2; do
    row "plantation $design (seed $seed) vs its own map" --plantation $design \
      --simulate $PLANT --range 15 --seed $seed
    row "plantation $design (seed $seed) vs another plantation" --plantation $design \
      --simulate $PLANT --range 15 --seed $seed --foreign
  done
done
row "Wild_V02 frames vs the Oxford_Stein map" --map $D/Oxford_Stein/map.csv \
  --frames $D/Wild_V02/trees.csv --poses $D/Wild_V02/poses.csv
row "Wild_V02 vs Wild_V01, NEES against the locally refined truth" --map $D/Wild_V01/map.csv \
  --frames $D/Wild_V02/trees.csv --poses $D/Wild_V02/poses.csv \
  --truth-offset 0.051,0.102,-0.039,-0.014 --truth-map $D/Wild_V02/map.csv

# Every shared stem map's views against every other stem map: any LOCALIZED answer is wrong.
maps=$(awk -F, 'NR > 1 && $2 >= 100 {print $1}' $S/INDEX.csv)
pairs=0 localized=0
for a in $maps; do
  for b in $maps; do
    [ "$a" = "$b" ] && continue
    n=$("$F" bench-reloc --map $S/$a.csv --foreign-map $S/$b.csv --simulate $PAIR --range 15 \
      --json --per-frame "$tmp/pair.csv" 2>/dev/null | python3 -c 'import json,sys; print(json.load(sys.stdin)["localized"])')
    tail -n +2 "$tmp/pair.csv" >> "$tmp/pairs.csv"
    pairs=$((pairs + 1)) localized=$((localized + n))
  done
done
python3 -c '
import csv, sys
cpu = sorted(float(r[14]) for r in csv.reader(open(sys.argv[1])))
wall = sorted(float(r[13]) for r in csv.reader(open(sys.argv[1])))
q = lambda v, p: v[min(len(v) - 1, int(p * len(v)))]
print("| every stem map vs every other (%s pairs) | %d | - | %s localized | %.2f / %.2f ms | %.2f ms | - | - |" % (
    sys.argv[2], len(cpu), sys.argv[3], q(wall, .5), q(wall, .95), q(cpu, .95)))
' "$tmp/pairs.csv" $pairs $localized
