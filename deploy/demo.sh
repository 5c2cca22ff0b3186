#!/usr/bin/env bash
# Command 1 of the README: installs dependencies, builds, starts forestmapd on its embedded
# SQLite database (./forestmap.db), uploads a demo forest map, relocalizes a simulated drone view
# in it and prints the true and the estimated pose; then does the same from a simulated LiDAR
# scan (trunk detection on the client, `relocalize --scan`). Then keeps serving until Ctrl-C
# (pass --no-serve to stop after the demo).
set -euo pipefail
cd "$(dirname "$0")/.."
serve=1
[ "${1:-}" = "--no-serve" ] && serve=0

bash deploy/build.sh --target forestmapd forestmap forestmap-lab
bin=build
addr=127.0.0.1:50051
export FORESTMAP_SERVER=$addr

"$bin/server/forestmapd" --db ./forestmap.db --listen "$addr" &
server=$!
trap 'kill $server 2>/dev/null; wait $server 2>/dev/null' EXIT
for _ in $(seq 50); do "$bin/client/cli/forestmap" map list >/dev/null 2>&1 && break; sleep 0.2; done
# Our server must be the one answering (another process may hold the port).
kill -0 $server 2>/dev/null || { echo "demo: forestmapd did not start (is $addr in use?)" >&2; exit 1; }

# A real surveyed stem map when ../shared/data is beside the clone, else a generated forest.
"$bin/client/lab/forestmap-lab" demo-data --out demo-out \
  --stemmap ../shared/data/stemmaps/spatstat_longleaf.csv
"$bin/client/cli/forestmap" map delete --yes demo >/dev/null 2>&1 || true
"$bin/client/cli/forestmap" map create demo --trees demo-out/map.csv \
  --description "ForestMap demo forest"
"$bin/client/cli/forestmap" map show demo
answer=$("$bin/client/cli/forestmap" relocalize demo --trees demo-out/query.csv)
truth=$(cat demo-out/truth.json)

field() { sed -n "s/.*\"$2\":\([^,}]*\).*/\1/p" <<<"$1"; }
echo
echo "drone's answer:  $answer"
printf 'true pose:       x=%9.3f  y=%9.3f  yaw=%8.2f deg\n' \
  "$(field "$truth" x)" "$(field "$truth" y)" "$(field "$truth" yaw_deg)"
if [ "$(field "$answer" status)" = '"localized"' ]; then
  printf 'estimated pose:  x=%9.3f  y=%9.3f  yaw=%8.2f deg  (%s trees matched, confidence %.2f)\n' \
    "$(field "$answer" x)" "$(field "$answer" y)" "$(field "$answer" yaw_deg)" \
    "$(field "$answer" inliers)" "$(field "$answer" confidence)"
  awk -v ex="$(field "$answer" x)" -v ey="$(field "$answer" y)" \
      -v tx="$(field "$truth" x)" -v ty="$(field "$truth" y)" \
      'BEGIN { printf "position error:  %.3f m\n", sqrt((ex-tx)^2 + (ey-ty)^2) }'
else
  echo "estimated pose:  none ($(field "$answer" status))"
fi

# The thin client's whole path: a simulated LiDAR scan (Ouster OS1-64, 3 m above the ground at
# the same place), trunks detected here, only the tree list sent to the server.
"$bin/client/lab/forestmap-lab" simulate --map demo-out/map.csv --scanner os1-64 \
  --pose "$(field "$truth" x),$(field "$truth" y),3,$(field "$truth" yaw_deg)" \
  --out demo-out/scan >/dev/null
scan_answer=$("$bin/client/cli/forestmap" relocalize demo --scan demo-out/scan/scan_000.pcd)
echo
echo "from a LiDAR scan: $scan_answer"
if [ "$(field "$scan_answer" status)" = '"localized"' ]; then
  awk -v ex="$(field "$scan_answer" x)" -v ey="$(field "$scan_answer" y)" \
      -v tx="$(field "$truth" x)" -v ty="$(field "$truth" y)" \
      'BEGIN { printf "position error:  %.3f m\n", sqrt((ex-tx)^2 + (ey-ty)^2) }'
fi

if [ $serve -eq 1 ]; then
  echo
  echo "forestmapd is serving on $addr with ./forestmap.db; try: $bin/client/cli/forestmap map list"
  echo "(Ctrl-C to stop)"
  wait $server
fi
