#!/usr/bin/env bash
# Server time of an Observe that weighs the evidence of absence (docs/performance.md, "The forest
# changes"): a generated forest of TREES trees (2,400 a hectare, DBH 10-40 cm, at least 1.2 m
# apart) in a map of forestmapd on SQLite; a third of the trees are then felled, and FRAMES
# single-frame requests, each from a drone of its own at a random place, detect the standing
# trees within 20 m (about 200 a frame) with 3 cm of noise. Prints the server time of each
# request's merge (ObserveResponse.server_time_ms), its median and 95th percentile.
#   tests/bench/observe_absence.sh [TREES=100000] [FRAMES=40] [PORT=50097]
# Binaries: $BIN (default build); $FORESTMAPD replaces the server.
set -euo pipefail
cd "$(dirname "$0")/../.."
trees=${1:-100000} frames=${2:-40} port=${3:-50097}
B=${BIN:-build}
F=$B/client/cli/forestmap
work=$(mktemp -d)
server=
trap 'kill $server 2>/dev/null || true; rm -rf "$work"' EXIT
/usr/bin/python3 - "$trees" "$frames" "$work" <<'PY'
import math, random, sys
n, frames, work = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
random.seed(1)
side = math.sqrt(n / 0.24)  # m: 2,400 trees a hectare
cell, grid, trees = 1.2, {}, []
while len(trees) < n:
    x, y = random.uniform(0, side), random.uniform(0, side)
    i, j = int(x / cell), int(y / cell)
    if any(math.hypot(x - t[0], y - t[1]) < cell
           for a in (i - 1, i, i + 1) for b in (j - 1, j, j + 1) for t in grid.get((a, b), [])):
        continue
    t = (x, y, random.uniform(0.1, 0.4))
    grid.setdefault((i, j), []).append(t)
    trees.append(t)
with open(f"{work}/map.csv", "w") as out:
    out.write("id,x,y,dbh\n")
    for k, (x, y, d) in enumerate(trees):
        out.write(f"{k + 1},{x:.3f},{y:.3f},{d:.3f}\n")
standing = [t for t in trees if random.random() >= 1 / 3]
for f in range(frames):
    sx, sy = random.uniform(30, side - 30), random.uniform(30, side - 30)
    with open(f"{work}/frame{f}.csv", "w") as out, open(f"{work}/pose{f}.csv", "w") as pose:
        out.write("frame,x,y,z,dbh\n")
        for x, y, d in standing:
            if math.hypot(x - sx, y - sy) <= 20:
                out.write(f"1,{x - sx + random.gauss(0, 0.03):.3f},"
                          f"{y - sy + random.gauss(0, 0.03):.3f},0,{d:.3f}\n")
        pose.write("frame,timestamp,x,y,z,qx,qy,qz,qw\n")
        pose.write(f"1,0,{sx:.3f},{sy:.3f},0,0,0,0,1\n")
PY
${FORESTMAPD:-$B/server/forestmapd} --db "$work/maps.db" --listen 127.0.0.1:$port >"$work/server.log" 2>&1 &
server=$!
for _ in $(seq 50); do "$F" --server 127.0.0.1:$port health >/dev/null 2>&1 && break; sleep 0.2; done
C=("$F" --server 127.0.0.1:$port)
"${C[@]}" map create m --trees "$work/map.csv" >/dev/null
for f in $(seq 0 $((frames - 1))); do
  "${C[@]}" observe m --frames "$work/frame$f.csv" --poses "$work/pose$f.csv" --source drone$f \
    --batch 1 >"$work/out" 2>"$work/err"
  echo "$(sed -n 's/.*server \([0-9.]*\) ms$/\1/p' "$work/err")" \
    "$(sed -n 's/.* \([0-9]*\) detections associated.*/\1/p' "$work/out")" \
    "$(sed -n 's/.* \([0-9]*\) map trees missed.*/\1/p' "$work/out")"
done | sort -n | awk -v trees="$trees" '{ ms[NR] = $1; seen += $2; missed += $3 } END {
  printf "%d observes of one frame into a %d-tree map (%.0f detections associated, %.0f map " \
    "trees missed a frame): server p50 %.1f ms, p95 %.1f ms, max %.1f ms\n", NR, trees, \
    seen / NR, missed / NR, ms[int(NR * 0.5 + 0.5)], ms[int(NR * 0.95 + 0.5)], ms[NR] }'
