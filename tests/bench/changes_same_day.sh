#!/usr/bin/env bash
# Real frames of a forest that did not change, through forestmapd (docs/performance.md, "The
# forest changes"): the Wild_V02 frames with their ground-truth poses (stated error 0.1 m and
# 0.2 deg; the session offset to the Wild_V01 map frame, a few cm, is left in that error) observed
# into a map of the Wild_V01 trees of the same day, cut into sources of FRAMES consecutive frames
# as if that many drones had flown the traversal in turn. Every map tree removed is wrong (or a
# tree of the reference map that no detector sees: the map is itself built from detections).
#   tests/bench/changes_same_day.sh [FRAMES=100] [PORT=50095]
# Binaries: $BIN (default build); data: $FORESTMAP_SHARED_DATA.
set -euo pipefail
cd "$(dirname "$0")/../.."
chunk=${1:-100} port=${2:-50095}
B=${BIN:-build}
F=$B/client/cli/forestmap
D=${FORESTMAP_SHARED_DATA:-../shared/data}/sequences
work=$(mktemp -d)
server=
trap 'kill $server 2>/dev/null || true; rm -rf "$work"' EXIT
$B/server/forestmapd --db "$work/maps.db" --listen 127.0.0.1:$port >"$work/server.log" 2>&1 &
server=$!
for _ in $(seq 50); do "$F" --server 127.0.0.1:$port health >/dev/null 2>&1 && break; sleep 0.2; done
C=("$F" --server 127.0.0.1:$port)
"${C[@]}" map create m --trees $D/Wild_V01/map.csv >/dev/null 2>&1
last=$(tail -n +2 $D/Wild_V02/poses.csv | cut -d, -f1 | sort -n | tail -1)
sources=0 t0=$(date +%s.%N)
for first in $(seq 0 "$chunk" "$last"); do
  "${C[@]}" observe m --frames $D/Wild_V02/trees.csv --poses $D/Wild_V02/poses.csv \
    --from-frame "$first" --to-frame $((first + chunk - 1)) --source "drone-$first" \
    --pose-sigma 0.1 --yaw-sigma 0.2 --batch 50 >/dev/null 2>&1
  sources=$((sources + 1))
done
seconds=$(echo "$(date +%s.%N) - $t0" | bc)
"${C[@]}" map export m --out "$work/updated.csv" 2>/dev/null
/usr/bin/python3 - "$D/Wild_V01/map.csv" "$work/updated.csv" "$sources" "$seconds" "$last" <<'PY'
import csv, sys
ids = lambda path: {int(r["id"]) for r in csv.DictReader(open(path, newline=""))}
original, updated = ids(sys.argv[1]), ids(sys.argv[2])
rows = list(csv.DictReader(open(sys.argv[2], newline="")))
removed = len(original - updated)
candidates = sum(r.get("status") == "candidate" for r in rows)
frames = int(sys.argv[5]) + 1
print(f"{len(original)} map trees, {frames} frames in {sys.argv[3]} sources: {removed} map trees "
      f"removed ({100 * removed / len(original):.2f}%), {candidates} candidates left; "
      f"{1000 * float(sys.argv[4]) / frames:.1f} ms a frame (client and server)")
PY
