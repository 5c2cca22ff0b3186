#!/usr/bin/env bash
# Issue 15's memory bar: a forestmapd on a fresh SQLite file; 16 clients each stream an upload of
# 2,000,000 trees and hold it open, 8 clients export a 1,000,000-tree map, read one message and
# stall (build/tests/bench/memory_bench). The server's RSS is sampled from /proc every 0.2 s;
# prints the bench's JSON line and the server's peak RSS (VmHWM) in MiB, and fails above BOUND_MIB.
#   tests/bench/memory_bench.sh [UPLOADS=16] [UPLOAD_TREES=2000000] [EXPORTS=8] [EXPORT_TREES=1000000]
# Env: PORT (50098), BOUND_MIB (1024), WORK (a temporary directory; needs ~6 GB of disk).
set -euo pipefail
cd "$(dirname "$0")/../.."
port=${PORT:-50098}
bound=${BOUND_MIB:-1024}
work=${WORK:-$(mktemp -d)}
build/server/forestmapd --db "$work/maps.db" --listen 127.0.0.1:$port >"$work/server.log" 2>&1 &
server=$!
trap 'kill $server 2>/dev/null; wait $server 2>/dev/null; rm -rf "$work"' EXIT
sleep 1
peak_sampled=0
(
  while kill -0 $server 2>/dev/null; do
    awk '/VmRSS/ {print $2}' /proc/$server/status 2>/dev/null
    sleep 0.2
  done
) >"$work/rss.txt" &
sampler=$!
build/tests/bench/memory_bench 127.0.0.1:$port "${1:-16}" "${2:-2000000}" "${3:-8}" "${4:-1000000}"
hwm=$(awk '/VmHWM/ {print int($2 / 1024)}' /proc/$server/status)
kill $sampler 2>/dev/null || true
peak_sampled=$(sort -n "$work/rss.txt" | tail -1)
echo "{\"server_peak_rss_mib\": $hwm, \"sampled_max_rss_mib\": $((peak_sampled / 1024)), \"bound_mib\": $bound, \"db_mib\": $(( $(du -sk "$work" | cut -f1) / 1024 ))}"
[ "$hwm" -le "$bound" ]
