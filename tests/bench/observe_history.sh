#!/usr/bin/env bash
# Observe against a map's accumulated history (docs/performance.md, "Observe and the history of
# the trees it touches"): a map of the Wild_V01 survey gets PASSES `forestmap observe` passes of
# all Wild_V01 frames (each under a source of its own), then COPIES copies of every drone row
# under other sources, written into SQLite directly (five more drones seeing the same detections
# would add such rows), and one client observes 3 frames at a time into it for SECONDS.
#   tests/bench/observe_history.sh [PASSES=1] [COPIES=0] [SECONDS=10] [PORT=50098]
# Binaries: $BIN (default build: BIN/server/forestmapd, ...); data: $FORESTMAP_SHARED_DATA;
# KEEP=FILE keeps a copy of the database.
set -euo pipefail
cd "$(dirname "$0")/../.."
passes=${1:-1} copies=${2:-0} seconds=${3:-10} port=${4:-50098}
B=${BIN:-build}
F=$B/client/cli/forestmap L=$B/client/lab/forestmap-lab
D=${FORESTMAP_SHARED_DATA:-../shared/data}/sequences/Wild_V01
work=$(mktemp -d)
server=
start_server() {
  $B/server/forestmapd --db "$work/maps.db" --listen 127.0.0.1:$port >>"$work/server.log" 2>&1 &
  server=$!
  for _ in $(seq 50); do "$F" --server 127.0.0.1:$port health >/dev/null 2>&1 && return; sleep 0.2; done
  echo "forestmapd did not start" >&2 && cat "$work/server.log" >&2 && exit 1
}
stop_server() { kill "$server" && wait "$server" 2>/dev/null || true; }
trap 'kill $server 2>/dev/null || true; [ -n "${KEEP:-}" ] && cp "$work/maps.db" "$KEEP"; rm -rf "$work"' EXIT
C=("$F" --server 127.0.0.1:$port)
start_server
"${C[@]}" map create m --trees $D/map.csv >/dev/null
for p in $(seq "$passes"); do
  t0=$(date +%s.%N)
  "${C[@]}" observe m --frames $D/trees.csv --poses $D/poses.csv --source pass$p --batch 200 \
    >/dev/null
  echo "pass $p: $(echo "$(date +%s.%N) - $t0" | bc) s"
done
if [ "$copies" -gt 0 ]; then
  stop_server
  # Copies of the current drone rows (not summaries: source '') under other sources, not folded;
  # the trees count their rows.
  sqlite3 "$work/maps.db" <<SQL
CREATE TEMP TABLE drone AS SELECT * FROM observations
  WHERE valid_to = 9223372036854775807 AND prior = 0 AND source != '';
WITH RECURSIVE k(n) AS (SELECT 1 UNION ALL SELECT n + 1 FROM k WHERE n < $copies)
INSERT INTO observations (map_id, tree_id, valid_from, valid_to, source, frame_id,
  detection_index, x, y, z, dbh, weight_xy, weight_dbh, sensor_x, sensor_y, sensor_z, prior,
  cell_x, cell_y)
SELECT map_id, tree_id, valid_from, valid_to, source || '-copy' || n, frame_id, detection_index,
  x, y, z, dbh, weight_xy, weight_dbh, sensor_x, sensor_y, sensor_z, prior, cell_x, cell_y
FROM drone, k;
UPDATE trees SET observations = (SELECT count(*) FROM observations AS o
  WHERE o.map_id = trees.map_id AND o.tree_id = trees.tree_id
    AND o.valid_to = 9223372036854775807 AND o.source != '')
WHERE valid_to = 9223372036854775807;
SQL
  start_server
fi
rows=$(sqlite3 "$work/maps.db" \
  "SELECT count(*) FROM observations WHERE valid_to = 9223372036854775807 AND source != ''")
echo "current observation rows: $rows (summary rows not counted)"
"$L" --server 127.0.0.1:$port bench-load m --frames $D/trees.csv --poses $D/poses.csv \
  --trees $D/map.csv --clients 1 --duration "$seconds" --mix 0,0,1,0 --observe-frames 3 \
  --observe-into m | python3 -c '
import json, sys
o = json.load(sys.stdin)["observe"]
print("observe: %d calls (%d ok), p50 %.0f ms, p95 %.0f ms" % (o["calls"], o["ok"], o["p50_ms"], o["p95_ms"]))'
stop_server
