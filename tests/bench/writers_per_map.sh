#!/usr/bin/env bash
# Issue 15, writers per map, end to end: forestmapd on a fresh SQLite file; `forestmap map create
# big --trees` of TREES trees (x, y, z, DBH, species) runs while `forestmap map create bN` (an
# empty map each) runs again and again, one after the other, until the big upload is done.
# Prints the big upload's time and the other creates' count, median and slowest time (CLI
# process start included): the slowest is the one that waited for the big upload's last
# transaction, if any did.
#   tests/bench/writers_per_map.sh [TREES=1000000] [BUILD_DIR=build]
set -euo pipefail
cd "$(dirname "$0")/../.."
trees=${1:-1000000}
build=${2:-build}
work=$(mktemp -d /tmp/forestmap-writers.XXXXXX)
port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
F=("$build/client/cli/forestmap" --server "127.0.0.1:$port")
"$build/server/forestmapd" --db "$work/maps.db" --listen "127.0.0.1:$port" --log-level warn \
  >"$work/server.log" 2>&1 &
server=$!
trap 'kill $server 2>/dev/null; wait $server 2>/dev/null; rm -rf "$work"' EXIT
python3 - "$work/big.csv" "$trees" <<'PY'
import random, sys
random.seed(1)
with open(sys.argv[1], "w") as out:
    out.write("x,y,z,dbh,species\n")
    for i in range(int(sys.argv[2])):
        out.write("%.2f,%.2f,%.2f,%.3f,%s\n" % (random.uniform(0, 3000), random.uniform(0, 3000),
                  random.uniform(100, 110), random.uniform(0.1, 0.6), random.choice("ABCD")))
PY
for _ in $(seq 50); do "${F[@]}" health >/dev/null 2>&1 && break; sleep 0.2; done
start=$EPOCHREALTIME
"${F[@]}" map create big --trees "$work/big.csv" 2>/dev/null | tail -1 >"$work/big.log" &
big=$!
times=()
n=0
while kill -0 $big 2>/dev/null; do
  n=$((n + 1))
  t0=$EPOCHREALTIME
  "${F[@]}" map create "b$n" >/dev/null
  times+=("$(awk -v a="$t0" -v b="$EPOCHREALTIME" 'BEGIN { print b - a }')")
done
wait $big || { cat "$work/big.log"; exit 1; }
echo "big upload of $trees trees: $(awk -v a="$start" -v b="$EPOCHREALTIME" 'BEGIN { printf "%.1f", b - a }') s ($(cat "$work/big.log"))"
printf '%s\n' "${times[@]}" | python3 -c '
import statistics, sys
t = sorted(float(x) * 1000 for x in sys.stdin)
print("other maps created meanwhile: %d, median %.0f ms, slowest %.0f ms" % (len(t), statistics.median(t), t[-1]))'
