#!/usr/bin/env bash
# Views that show little (the edge of a survey, neighbouring plot maps, sparse stands) and the
# time of "not here", measured on this machine:
#   tests/bench/relocalization_coverage.sh [--quick]   (after ./deploy/build.sh; --quick: fewer
#                                                        views; FORESTMAP_BIN: the
#                                                        forestmap-lab binary to measure)
# Prints one markdown row per case: views, answerable views (>= 8 mapped trees in sight; >= 10
# on the neighbour's map for plots), recall (0.5 m / 5 deg) over them and over the views with
# >= 12 mapped trees in sight, wrong answers, wall and CPU time per query (p95 of all answers,
# NOT_FOUND included) and the mean NEES of the correct answers (3 dof).
set -euo pipefail
cd "$(dirname "$0")/../.."
F=${FORESTMAP_BIN:-build/client/lab/forestmap-lab}
DATA=${FORESTMAP_SHARED_DATA:-../shared/data}
D=$DATA/sequences S=$DATA/stemmaps
EDGE=300 PAIRS=100 SPARSE=300 MOSAIC=1000000 STEP=1
if [ "${1:-}" = "--quick" ]; then EDGE=60 PAIRS=30 SPARSE=60 MOSAIC=200000 STEP=5; fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# summarize NAME CSV... : one row over the answers of every per-frame CSV given (JSON beside).
summarize() {
  python3 - "$@" <<'EOF'
import csv, json, sys
name, files = sys.argv[1], sys.argv[2:]
rows, nees, weight = [], 0.0, 0
for f in files:
    rows += list(csv.DictReader(open(f)))
    r = json.load(open(f + ".json"))
    nees += r["nees_xy_yaw_mean"] * r["localized"]
    weight += r["localized"]
q = lambda v, p: sorted(v)[min(len(v) - 1, int(p * len(v)))] if v else 0
def ok(x): return x["status"] == "localized" and float(x["error_xy_m"]) <= 0.5 and float(x["error_yaw_deg"]) <= 5
ans = [x for x in rows if x["answerable"] == "1"]
rich = [x for x in rows if int(x["mapped_in_sight"]) >= 12]
wrong = sum(1 for x in rows if x["status"] == "localized" and (float(x["error_xy_m"]) > 1 or float(x["error_yaw_deg"]) > 5))
pct = lambda a, b: "%.1f%% (%d/%d)" % (100.0 * a / b, a, b) if b else "-"
nf = sum(1 for x in rows if x["status"] == "not_found")
print("| %s | %d | %s | %s | %d (%d n.f.) | %.2f / %.2f ms | %.2f ms | %s |" % (
    name, len(rows), pct(sum(ok(x) for x in ans), len(ans)), pct(sum(ok(x) for x in rich), len(rich)),
    wrong, nf, q([float(x["ms"]) for x in rows], .5), q([float(x["ms"]) for x in rows], .95),
    q([float(x["cpu_ms"]) for x in rows], .95), "%.2f" % (nees / weight) if weight else "-"))
EOF
}

# run TAG bench-reloc-arguments... : per-frame CSV in $tmp/TAG.csv, the JSON report beside it.
run() {
  local tag=$1; shift
  "$F" bench-reloc "$@" --json --per-frame "$tmp/$tag.csv" 2>/dev/null >"$tmp/$tag.csv.json"
}

echo "| case | views | recall (answerable) | recall (>= 12 mapped in sight) | wrong | wall p50 / p95 | CPU p95 | mean NEES |"
echo "|---|---|---|---|---|---|---|---|"
big=$(awk -F, 'NR > 1 && $2 >= 200 {print $1}' $S/INDEX.csv)
for map in $big; do
  run "edge_$map" --map $S/$map.csv --edge --simulate $EDGE --range 15 --seed 1
done
summarize "edge views, every stem map of >= 200 trees, $EDGE each" $tmp/edge_*.csv
for map in $(awk -F, 'NR > 1 {print $1}' $S/INDEX.csv); do
  run "plots_$map" --map $S/$map.csv --overlap --simulate $PAIRS --answerable-trees 10 --seed 1 ||
    rm -f "$tmp/plots_$map.csv" "$tmp/plots_$map.csv.json"  # too small for two plots
done
summarize "neighbouring plots (20 m radius, 20-30 m apart), every stem map, $PAIRS pairs each" \
  $tmp/plots_*.csv
MAPS=$S/siplab_boreasNS.csv,$S/spatstat_longleaf.csv,$S/spatstat_urkiola.csv,$S/spatstat_waka.csv,$S/ads_Allogny.csv,$S/ads_BPoirier.csv
for seed in 1 2 3; do
  run "sparse_$seed" --mosaic $MAPS --mosaic-trees $MOSAIC --no-dbh --max-density 0.03 \
    --miss 0.05 --far-miss 0.4 --noise-per-m 0.005 --simulate $SPARSE --range 15 --seed $seed
  summarize "mosaic seed $seed without DBH, views in stands under 0.03 trees/m^2" $tmp/sparse_$seed.csv
done
V02="--frames $D/Wild_V02/trees.csv --poses $D/Wild_V02/poses.csv --step $STEP"
run v01 --map $D/Wild_V01/map.csv $V02 --truth-offset 0.051,0.102,-0.039,-0.014 \
  --truth-map $D/Wild_V02/map.csv
summarize "Wild_V02 frames vs Wild_V01 (truth aligned locally)" $tmp/v01.csv
run stein_v02 --map $D/Oxford_Stein/map.csv $V02
summarize "Wild_V02 frames vs Oxford_Stein (another forest)" $tmp/stein_v02.csv
run stein --map $D/Oxford_Stein/map.csv --frames $D/Oxford_Stein/trees.csv \
  --poses $D/Oxford_Stein/poses.csv --step $STEP
summarize "Oxford_Stein frames vs its map" $tmp/stein.csv
