#!/usr/bin/env bash
# Issue 4's end-to-end figure through the real server: simulated OS1-64 scans of the longleaf
# stem map, each through `forestmap relocalize --scan` (trunks detected on the client, only the
# tree list sent to forestmapd), scored against the simulator's poses.
#   tests/bench/scan_to_pose.sh [SCANS] [IMU_DEG]
# SCANS (default 200); IMU_DEG: also send gravity as the drone's IMU would, the true one tilted
# by a Gaussian angle of this RMS (deg) about a random horizontal axis (seeded).
set -euo pipefail
cd "$(dirname "$0")/../.."
F=build/client/cli/forestmap L=build/client/lab/forestmap-lab S=../shared/data/stemmaps
scans=${1:-200} imu=${2:-}
work=$(mktemp -d)
build/server/forestmapd --db "$work/e2e.db" --listen 127.0.0.1:50098 >"$work/server.log" 2>&1 &
server=$!
trap 'kill $server 2>/dev/null; rm -rf "$work"' EXIT
"$L" simulate --map $S/spatstat_longleaf.csv --random-poses "$scans" --scanner os1-64 --seed 7 \
  --out "$work/scans" 2>/dev/null
"$F" --server 127.0.0.1:50098 map create longleaf --trees "$work/scans/map.csv" >/dev/null 2>&1
python3 - "$work/scans/poses.csv" "$imu" >"$work/gravity.txt" <<'PY'
import csv, math, random, sys
random.seed(7)
for r in csv.DictReader(open(sys.argv[1])):
    qx, qy, qz, qw = (float(r[k]) for k in ("qx", "qy", "qz", "qw"))
    down = [0.0, 0.0, -1.0]
    if sys.argv[2]:
        a, t = random.uniform(-math.pi, math.pi), math.radians(random.gauss(0, float(sys.argv[2])))
        ax, ay = math.cos(a), math.sin(a)  # tilt `down` about the horizontal axis (ax, ay, 0)
        down = [-ay * math.sin(t), ax * math.sin(t), -math.cos(t)]
    # sensor_from_map = R^T: rows of R are the columns of R^T.
    R = [[1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
         [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
         [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)]]
    g = [sum(R[i][j] * down[i] for i in range(3)) for j in range(3)]
    print(r["frame"], "%.6f,%.6f,%.6f" % tuple(g))
PY
while read -r frame gravity; do
  extra=()
  [ -n "$imu" ] && extra=(--gravity "$gravity")
  printf -v name "%s/scans/scan_%03d.pcd" "$work" "$frame"
  "$F" --server 127.0.0.1:50098 relocalize longleaf --scan "$name" "${extra[@]}" 2>/dev/null ||
    echo '{"status":"failed"}'
done <"$work/gravity.txt" >"$work/answers.jsonl"
python3 - "$work/scans/poses.csv" "$work/answers.jsonl" <<'PY'
import csv, json, math, sys
poses = list(csv.DictReader(open(sys.argv[1])))
answers = [json.loads(line) for line in open(sys.argv[2])]
within = wrong = localized = 0
for pose, a in zip(poses, answers):
    if a["status"] != "localized":
        continue
    localized += 1
    e = math.hypot(a["x"] - float(pose["x"]), a["y"] - float(pose["y"]))
    within += e <= 0.3
    wrong += e > 1.0
n = len(poses)
print("scans %d, localized %d, within 0.3 m %d (%.1f%%), more than 1 m off %d"
      % (n, localized, within, 100.0 * within / n, wrong))
PY
