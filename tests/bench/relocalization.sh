#!/usr/bin/env bash
# Every relocalization figure of docs/performance.md "Relocalization", measured on this machine:
#   tests/bench/relocalization.sh [--quick]      (after ./deploy/build.sh; --quick: every 5th
#                                                 frame, 200 views, a 100,000-tree map)
# Prints one markdown row per case. Latency is wall time per query in one thread; a busy
# machine inflates it (bench-reloc --per-frame FILE also records CPU time per query).
set -euo pipefail
cd "$(dirname "$0")/../.."
F=build/client/cli/forestmap L=build/client/lab/forestmap-lab D=../shared/data/sequences S=../shared/data/stemmaps
STEP=1 VIEWS=1000 BIG=1000000
if [ "${1:-}" = "--quick" ]; then STEP=5 VIEWS=200 BIG=100000; fi
V02="--frames $D/Wild_V02/trees.csv --poses $D/Wild_V02/poses.csv --truth-offset 0.051,0.102,-0.039,-0.014"
STEIN="--frames $D/Oxford_Stein/trees.csv --poses $D/Oxford_Stein/poses.csv"

row() {  # row NAME bench-reloc-arguments...
  local name=$1; shift
  "$L" bench-reloc "$@" --json 2>/dev/null | python3 -c '
import json, sys
r = json.load(sys.stdin)
print("| %s | %d | %d | %.2f%% | %.2f%% | %d (%d loc., %d amb., %d n.f.) | %.3f m | %.2f / %.2f ms | %.1f s, %.0f B/tree resident |" % (
    sys.argv[1], r["frames"], r["answerable"], 100 * r["recall"], 100 * r["strict_recall"],
    r["wrong"], r["localized"], r["ambiguous"], r["not_found"], r["error_xy_p50_m"],
    r["time_p50_ms"], r["time_p95_ms"], r["index_build_ms"] / 1000, r["index_resident_bytes_per_tree"]))
' "$name"
}

echo "| case | frames | answerable | recall | strict | wrong (outcomes) | median error | latency p50 / p95 | index |"
echo "|---|---|---|---|---|---|---|---|---|"
row "Wild_V02 vs Wild_V01 map, no prior" --map $D/Wild_V01/map.csv $V02 --step $STEP
row "same, truth aligned locally (--truth-map)" --map $D/Wild_V01/map.csv $V02 --step $STEP \
  --truth-map $D/Wild_V02/map.csv
row "Oxford_Stein vs its map, no prior" --map $D/Oxford_Stein/map.csv $STEIN --step $STEP
row "Wild_V02, prior (truth + 3 m, radius 10 m)" --map $D/Wild_V01/map.csv $V02 --step $STEP \
  --prior-noise 3
row "Oxford_Stein, prior (truth + 3 m, radius 10 m)" --map $D/Oxford_Stein/map.csv $STEIN \
  --step $STEP --prior-noise 3
row "Wild_V02 vs the Oxford_Stein map (wrong forest)" --map $D/Oxford_Stein/map.csv \
  --frames $D/Wild_V02/trees.csv --poses $D/Wild_V02/poses.csv --step $STEP
for map in $(awk -F, 'NR > 1 && $2 >= 100 {print $1}' $S/INDEX.csv); do
  row "$VIEWS simulated views of $map" --map $S/$map.csv --simulate $VIEWS --range 15
done
row "$VIEWS views of a generated $BIG-tree map (boreasNP statistics)" --generate $BIG \
  --like $S/siplab_boreasNP.csv --simulate $VIEWS --range 15

# Server throughput: forestmapd on a scratch database, the Wild_V01 map, 8 client threads.
db=$(mktemp -d)
build/server/forestmapd --db "$db/bench.db" --listen 127.0.0.1:50097 >"$db/server.log" 2>&1 &
server=$!
trap 'kill $server 2>/dev/null; rm -rf "$db"' EXIT
sleep 1
"$F" --server 127.0.0.1:50097 map create venman --trees $D/Wild_V01/map.csv >/dev/null
echo
echo "Server throughput (8 client threads on the same machine, Wild_V02 frames vs the Wild_V01 map):"
"$L" --server 127.0.0.1:50097 bench-server venman --frames $D/Wild_V02/trees.csv \
  --concurrency 8 --requests 3000
