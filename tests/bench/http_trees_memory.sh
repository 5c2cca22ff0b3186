#!/usr/bin/env bash
# The web page's tree endpoint and server memory: a forestmapd on a fresh SQLite file with one
# generated map of TREES trees; REQUESTS sequential `curl /api/maps/huge/trees` (the whole map as
# JSON each); the server's RSS (/proc/PID/status VmRSS) before, after each request, and its growth.
# Fails when the growth exceeds BOUND_MIB.
#   tests/bench/http_trees_memory.sh [REQUESTS=14] [TREES=300000]
# Env: FORESTMAP_BUILD (build), BOUND_MIB (150), WORK (a temporary directory).
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${FORESTMAP_BUILD:-build}
requests=${1:-14}
trees=${2:-300000}
bound=${BOUND_MIB:-150}
work=${WORK:-$(mktemp -d)}
server=
trap '[ -n "$server" ] && kill $server 2>/dev/null; wait 2>/dev/null; rm -rf "$work"' EXIT
awk -v n="$trees" 'BEGIN { srand(7); print "id,x,y,dbh";
  for (i = 0; i < n; i++) printf "%d,%.3f,%.3f,%.3f\n", i, rand() * 3000, rand() * 3000, 0.1 + rand() * 0.6 }' \
  >"$work/trees.csv"
"$build/server/forestmapd" --db "$work/maps.db" --listen 127.0.0.1:0 --http 127.0.0.1:0 \
  >"$work/server.log" 2>&1 &
server=$!
for _ in $(seq 100); do grep -q "web page on" "$work/server.log" && break; sleep 0.1; done
grpc=$(grep -o 'serving on [^ ,]*' "$work/server.log" | sed 's/.*://')
http=$(grep -o 'web page on http://[^/]*' "$work/server.log" | sed 's/.*://')
"$build/client/cli/forestmap" --server 127.0.0.1:$grpc map create huge --trees "$work/trees.csv" \
  >/dev/null 2>&1
rss() { awk '/VmRSS/ {print int($2 / 1024)}' /proc/$server/status; }
before=$(rss)
echo "requests=$requests trees=$trees rss_before_mib=$before"
for i in $(seq "$requests"); do
  bytes=$(curl -sf "http://127.0.0.1:$http/api/maps/huge/trees" | wc -c)
  echo "request $i: $bytes bytes, rss $(rss) MiB"
done
after=$(rss)
echo "{\"rss_before_mib\": $before, \"rss_after_mib\": $after, \"growth_mib\": $((after - before)), \"bound_mib\": $bound}"
[ $((after - before)) -le "$bound" ]
