#!/usr/bin/env bash
# OGC API - Features on a huge map: a forestmapd on a fresh SQLite file with one generated map of
# TREES trees in EPSG:2959; a client pages through all of it (items?limit=LIMIT, following the
# `next` links, the trees moved to WGS 84 by the server), once per LIMIT; prints pages, trees,
# seconds and the server's RSS (/proc/PID/status VmRSS) before and at its peak.
#   tests/bench/ogc_paging.sh [TREES=1000000] [LIMIT...=10000 1000]
# Env: FORESTMAP_BUILD (build), WORK (a temporary directory).
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${FORESTMAP_BUILD:-build}
trees=${1:-1000000}
shift $(($# > 0 ? 1 : 0))
limits=("$@")
[ ${#limits[@]} -gt 0 ] || limits=(10000 1000)
work=${WORK:-$(mktemp -d)}
server=
trap '[ -n "$server" ] && kill $server 2>/dev/null; wait 2>/dev/null; rm -rf "$work"' EXIT
awk -v n="$trees" 'BEGIN { srand(7); print "id,x,y,dbh";
  for (i = 0; i < n; i++) printf "%d,%.3f,%.3f,%.3f\n", i + 1, 312000 + rand() * 5000,
    5096000 + rand() * 5000, 0.1 + rand() * 0.6 }' >"$work/trees.csv"
"$build/server/forestmapd" --db "$work/maps.db" --listen 127.0.0.1:0 --http 127.0.0.1:0 \
  >"$work/server.log" 2>&1 &
server=$!
for _ in $(seq 100); do grep -q "web page on" "$work/server.log" && break; sleep 0.1; done
grpc=$(grep -o 'serving on [^ ,]*' "$work/server.log" | sed 's/.*://')
http=$(grep -o 'web page on http://[^/]*' "$work/server.log" | sed 's/.*://')
"$build/client/cli/forestmap" --server 127.0.0.1:$grpc map create huge --crs EPSG:2959 \
  --trees "$work/trees.csv" >/dev/null
for limit in "${limits[@]}"; do
  python3 - "$http" "$limit" "$server" <<'PY'
import json, sys, time, urllib.request
port, limit, pid = sys.argv[1:4]
def rss():
    with open(f"/proc/{pid}/status") as status:
        return next(int(l.split()[1]) // 1024 for l in status if l.startswith("VmRSS"))
url = f"http://127.0.0.1:{port}/ogc/collections/huge/items?limit={limit}"
before, start, pages, trees, peak = rss(), time.time(), 0, 0, 0
while url:
    page = json.load(urllib.request.urlopen(url))
    pages, trees, peak = pages + 1, trees + page["numberReturned"], max(peak, rss())
    url = next((l["href"] for l in page["links"] if l["rel"] == "next"), None)
print(f"limit={limit} pages={pages} trees={trees} seconds={time.time() - start:.1f} "
      f"rss_before_mib={before} rss_peak_mib={peak}")
PY
done
