#!/usr/bin/env bash
# The forest changes, through forestmapd (docs/performance.md, "The forest changes"): a stem
# map's simulated future and drone passes over it (`forestmap-lab bench-changes --write`, which
# also prints its in-process figures), each pass observed by `forestmap observe` into a map of the
# original survey under a source of its own (poses with the stated error), then the map's export
# scored against the future's truth (tests/bench/changes_server.py).
#   tests/bench/changes_server.sh STEM_MAP.csv [SEED=1] [PORT=50096] [-- bench-changes flags]
# Binaries: $BIN (default build).
set -euo pipefail
cd "$(dirname "$0")/../.."
map=$1 seed=${2:-1} port=${3:-50096}
shift $(($# < 3 ? $# : 3)); [ "${1:-}" = "--" ] && shift
B=${BIN:-build}
F=$B/client/cli/forestmap L=$B/client/lab/forestmap-lab
work=$(mktemp -d)
server=
trap 'kill $server 2>/dev/null || true; rm -rf "$work"' EXIT
echo "in process:"
"$L" bench-changes --map "$map" --seed "$seed" --reloc-views 0 --write "$work/passes" "$@" \
  | sed 's/^/  /'
$B/server/forestmapd --db "$work/maps.db" --listen 127.0.0.1:$port >"$work/server.log" 2>&1 &
server=$!
for _ in $(seq 50); do "$F" --server 127.0.0.1:$port health >/dev/null 2>&1 && break; sleep 0.2; done
C=("$F" --server 127.0.0.1:$port)
"${C[@]}" map create m --trees "$map" >/dev/null
t0=$(date +%s.%N)
for trees in "$work"/passes/pass*_trees.csv; do
  pass=$(basename "$trees" _trees.csv)
  "${C[@]}" observe m --frames "$trees" --poses "$work/passes/${pass}_poses.csv" --source "$pass" \
    --pose-sigma 0.05 --yaw-sigma 0.2 --batch ${BATCH:-50} 2>/dev/null | sed "s/^/  $pass: /"
done
echo "observed in $(echo "$(date +%s.%N) - $t0" | bc) s"
"${C[@]}" map export m --out "$work/updated.csv" 2>/dev/null
echo "through forestmapd:"
/usr/bin/python3 tests/bench/changes_server.py "$map" "$work/updated.csv" "$work/passes/truth.json"
