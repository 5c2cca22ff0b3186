#!/usr/bin/env bash
# Relocalizations per second with 1, 2 and 3 forestmapd replicas on one PostgreSQL (a throwaway
# cluster, tests/pg_fixture), through `forestmap-lab bench-server` with --server listing the replicas
# (client threads spread over them). PIN=1 pins replica i to core (i mod cores) with taskset.
# Prints one JSON line per replica count, plus database and memory sizing.
# Usage: tests/bench/replicas.sh [BUILD_DIR]   (REQUESTS=2000 CONCURRENCY=6 PIN=0)
set -euo pipefail
build="${1:-build}"
data="${FORESTMAP_SHARED_DATA:-$(dirname "$0")/../../../shared/data}/sequences/Wild_V01"
requests="${REQUESTS:-2000}"
concurrency="${CONCURRENCY:-6}"
pin="${PIN:-0}"
cores="$(nproc)"
state="$(mktemp /tmp/forestmap-bench-pg-XXXXXX)"
pids=()
cleanup() {
  for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null || true; done
  wait 2>/dev/null || true
  "$build/tests/pg_fixture" stop "$state" >/dev/null || true
  rm -f "$state"
}
trap cleanup EXIT
"$build/tests/pg_fixture" start "$state" >/dev/null
url="$(head -1 "$state")"
psql -q "$url/postgres" -c "CREATE DATABASE bench"
db="$url/bench"
free_port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }

addresses=()
for replica in 1 2 3; do
  port="$(free_port)"
  launcher=()
  [ "$pin" = 1 ] && launcher=(taskset -c $(( (replica - 1) % cores )))
  "${launcher[@]}" "$build/server/forestmapd" --db "$db" --listen "127.0.0.1:$port" 2>/dev/null &
  pids+=($!)
  addresses+=("127.0.0.1:$port")
  until "$build/client/cli/forestmap" --server "127.0.0.1:$port" health --timeout 0.5 >/dev/null 2>&1; do
    sleep 0.1
  done
  if [ "$replica" = 1 ]; then
    rss_empty_kib="$(ps -o rss= -p "${pids[0]}")"
    "$build/client/cli/forestmap" --server "${addresses[0]}" map create wild --trees "$data/map.csv" >/dev/null
  fi
  servers="$(IFS=,; echo "${addresses[*]}")"
  # Warm every replica's index (one relocalization each), then measure.
  "$build/client/lab/forestmap-lab" --server "$servers" bench-server wild --frames "$data/trees.csv" \
    --requests $((replica * 4)) --concurrency "$replica" >/dev/null
  result="$("$build/client/lab/forestmap-lab" --server "$servers" bench-server wild \
    --frames "$data/trees.csv" --requests "$requests" --concurrency "$concurrency")"
  echo "{\"replicas\": $replica, \"pinned\": $pin, \"cores\": $cores, \"result\": $result}"
done
trees="$(psql -tA "$db" -c "SELECT COUNT(*) FROM trees")"
bytes="$(psql -tA "$db" -c "SELECT pg_database_size('bench')")"
empty="$(psql -tA "$url/postgres" -c "SELECT pg_database_size('template0')")"
rss_kib="$(ps -o rss= -p "${pids[0]}")"
echo "{\"map_trees\": $trees, \"database_bytes\": $bytes, \"empty_database_bytes\": $empty, \"replica1_rss_kib_before_map\": $rss_empty_kib, \"replica1_rss_kib_with_index\": $rss_kib}"
