#!/usr/bin/env bash
# Issue 15's load bar through the real server: forestmapd on a temporary database with the real
# Wild_V01 map, then `forestmap-lab bench-load` with CLIENTS clients for SECONDS: relocalize and track
# Wild_V02 frames in that map, observe and upload into one small map per client. Prints the
# report (per-kind calls, failures by status, latency percentiles, the server's RSS over time)
# and a summary; fails when a kind had no successful call or any call failed other than with
# RESOURCE_EXHAUSTED (a stated limit, counted apart).
#   tests/bench/load.sh [SECONDS=600] [CLIENTS=64] [PORT (default: a free one)]
# Environment: FORESTMAP_BUILD (build dir, default build), FORESTMAP_SHARED_DATA (default
# ../shared/data), LOAD_NICE (nice level of server and clients, default 0), LOAD_REPORT (also
# write the JSON report there). Without the data it skips (exit 77), unless CI=true.
set -euo pipefail
cd "$(dirname "$0")/../.."
seconds=${1:-600} clients=${2:-64}
port=${3:-$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')}
build=${FORESTMAP_BUILD:-build}
data=${FORESTMAP_SHARED_DATA:-../shared/data}/sequences
F=("$build/client/cli/forestmap" --server "127.0.0.1:$port")
L=("$build/client/lab/forestmap-lab" --server "127.0.0.1:$port")
if [ ! -f "$data/Wild_V01/map.csv" ] || [ ! -f "$data/Wild_V02/trees.csv" ]; then
  echo "load.sh: no Wild_V01/Wild_V02 data under $data"
  [ "${CI:-}" = true ] && exit 1
  exit 77
fi
work=$(mktemp -d /tmp/forestmap-load.XXXXXX)
nice -n "${LOAD_NICE:-0}" "$build/server/forestmapd" --db "$work/maps.db" \
  --listen "127.0.0.1:$port" --log-level warn >"$work/server.log" 2>&1 &
server=$!
trap 'kill $server 2>/dev/null; wait $server 2>/dev/null; rm -rf "$work"' EXIT
for _ in $(seq 50); do "${F[@]}" health >/dev/null 2>&1 && break; sleep 0.2; done
"${F[@]}" map create load-shared --trees "$data/Wild_V01/map.csv" >"$work/create.log" 2>&1 ||
  { cat "$work/create.log" "$work/server.log"; exit 1; }
echo "load.sh: forestmapd pid $server, $clients clients for $seconds s (nice ${LOAD_NICE:-0})"
nice -n "${LOAD_NICE:-0}" "${L[@]}" bench-load load-shared --frames "$data/Wild_V02/trees.csv" \
  --poses "$data/Wild_V02/poses.csv" --trees "$data/Wild_V01/map.csv" --clients "$clients" \
  --duration "$seconds" --server-pid "$server" --rss-interval "$((seconds >= 120 ? 10 : 2))" \
  --keep-maps >"$work/report.json"  # the database is thrown away
[ -z "${LOAD_REPORT:-}" ] || cp "$work/report.json" "$LOAD_REPORT"
cat "$work/report.json"
kill -0 "$server" || { echo "load.sh: forestmapd died"; tail -20 "$work/server.log"; exit 1; }
echo "load.sh: database $(du -m "$work/maps.db" | cut -f1) MiB after the run (history kept);" \
  "server log: $(grep -c ' error ' "$work/server.log" || true) error lines"
python3 - "$work/report.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
bad = []
print("kind        calls    ok   calls/s  p50 ms  p95 ms  p99 ms  failed  exhausted  localized")
for kind in ("relocalize", "track", "observe", "upload"):
    k = r[kind]
    failed = sum(k["failed"].values())
    print("%-10s %6d %6d %8.1f %7.1f %7.1f %7.1f %7d %10d %10s  %s" % (kind, k["calls"], k["ok"],
          k["calls_per_second"], k["p50_ms"], k["p95_ms"], k["p99_ms"], failed,
          k["resource_exhausted"], k.get("localized", "-"), k["failed"] or ""))
    if k["ok"] == 0 or failed:
        bad.append(kind)
rss = r.get("server_rss", {})
if "after_warmup_min_mib" in rss:
    print("server RSS after %.0f s warm-up: %.1f .. %.1f MiB (final %.1f MiB; %d samples)" % (
        rss["after_warmup_s"], rss["after_warmup_min_mib"], rss["after_warmup_max_mib"],
        rss["final_mib"], len(rss["samples"])))
if bad:
    sys.exit("load.sh: failed calls or no successful call: " + ", ".join(bad))
PY
