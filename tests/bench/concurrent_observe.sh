#!/usr/bin/env bash
# Issue 5's concurrency figure through the real server: all Wild_V01 frames (with their poses)
# uploaded by one `forestmap observe`, then the four quarters by four `forestmap observe` at the
# same time into a second map; wall times of both, and how many confirmed trees of the two maps
# differ (no tree of the other map within 1 cm).
#   tests/bench/concurrent_observe.sh [PORT]
# Data: $FORESTMAP_SHARED_DATA (default ../shared/data).
set -euo pipefail
cd "$(dirname "$0")/../.."
F=build/client/cli/forestmap D=${FORESTMAP_SHARED_DATA:-../shared/data}/sequences/Wild_V01
port=${1:-50097}
work=$(mktemp -d)
build/server/forestmapd --db "$work/maps.db" --listen 127.0.0.1:$port >"$work/server.log" 2>&1 &
server=$!
trap 'kill $server 2>/dev/null; rm -rf "$work"' EXIT
sleep 1
C=("$F" --server 127.0.0.1:$port)
"${C[@]}" map create sequential >/dev/null
"${C[@]}" map create concurrent >/dev/null
start=$(date +%s.%N)
"${C[@]}" observe sequential --frames $D/trees.csv --poses $D/poses.csv --source seq >/dev/null 2>&1
mid=$(date +%s.%N)
pids=()
for q in 0 1 2 3; do
  # Frame ids are 0..1450: the quarters of the concurrent test (frames.size() * q / 4).
  from=$((1451 * q / 4)) to=$((1451 * (q + 1) / 4 - 1))
  # Sources named against the frame order (drone-d has the first quarter).
  source=(drone-d drone-c drone-b drone-a)
  "${C[@]}" observe concurrent --frames $D/trees.csv --poses $D/poses.csv --source ${source[q]} \
    --from-frame $from --to-frame $to >/dev/null 2>&1 &
  pids+=($!)
done
failed=0
for pid in "${pids[@]}"; do wait "$pid" || failed=$((failed + 1)); done
end=$(date +%s.%N)
"${C[@]}" map export sequential --out "$work/sequential.csv" >/dev/null 2>&1
"${C[@]}" map export concurrent --out "$work/concurrent.csv" >/dev/null 2>&1
python3 - "$work/sequential.csv" "$work/concurrent.csv" "$start" "$mid" "$end" "$failed" <<'PY'
import csv, math, sys
def confirmed(path):
    return [(float(r["x"]), float(r["y"])) for r in csv.DictReader(open(path))
            if r.get("status") == "confirmed"]
def unmatched(a, b):
    cells = {}
    for x, y in b:
        cells.setdefault((math.floor(x / 0.01), math.floor(y / 0.01)), []).append((x, y))
    n = 0
    for x, y in a:
        cx, cy = math.floor(x / 0.01), math.floor(y / 0.01)
        near = [p for dx in (-1, 0, 1) for dy in (-1, 0, 1)
                for p in cells.get((cx + dx, cy + dy), [])]
        n += not any(math.hypot(x - p[0], y - p[1]) <= 0.01 for p in near)
    return n
s, c = confirmed(sys.argv[1]), confirmed(sys.argv[2])
start, mid, end = (float(v) for v in sys.argv[3:6])
print("sequential: %d confirmed, %.1f s; concurrent (4 clients): %d confirmed, %.1f s, %s failed"
      % (len(s), mid - start, len(c), end - mid, sys.argv[6]))
print("confirmed trees without a twin within 1 cm: sequential %d, concurrent %d; "
      "all positions bit-identical: %s"
      % (unmatched(s, c), unmatched(c, s), sorted(s) == sorted(c)))
PY
