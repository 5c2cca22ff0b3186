#!/usr/bin/env bash
# Legitimate load with attacks mixed in, through a real forestmapd on loopback with tokens, the
# web page and the metrics port: `forestmap-lab bench-load` (CLIENTS clients relocalizing,
# tracking, observing and uploading with their own admin token) runs for SECONDS while
# tests/bench/attack.py sends unknown gRPC methods with quotes and newlines, holds silent
# UploadTrees / ExportTrees / Track streams without a token and with a read token (timing an
# admin upload and export meanwhile), reuses request ids on another map and by another caller,
# and holds half-open HTTP connections to both web ports. Afterwards /metrics must pass
# `promtool check metrics`, stay under 1 MB and hold no forged line. Prints the load report,
# the attack report and a verdict; fails when a legitimate call failed (RESOURCE_EXHAUSTED, a
# stated limit, is counted apart) or an attack bar was missed.
#   tests/bench/attack.sh [SECONDS=600] [CLIENTS=8]
# Environment: FORESTMAP_BUILD (build dir, default build; needs forestmapd, forestmap,
# forestmap-lab and the forestmap_python target), FORESTMAP_SHARED_DATA (default ../shared/data).
# Needs python3 with grpcio (Debian python3-grpcio) and promtool. Without the data it skips
# (exit 77), unless CI=true.
set -euo pipefail
cd "$(dirname "$0")/../.."
seconds=${1:-600} clients=${2:-8}
build=${FORESTMAP_BUILD:-build}
data=${FORESTMAP_SHARED_DATA:-../shared/data}/sequences
if [ ! -f "$data/Wild_V01/map.csv" ] || [ ! -f "$data/Wild_V02/trees.csv" ]; then
  echo "attack.sh: no Wild_V01/Wild_V02 data under $data"
  [ "${CI:-}" = true ] && exit 1
  exit 77
fi
free_port() { python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
grpc_port=$(free_port) http_port=$(free_port) metrics_port=$(free_port)
work=$(mktemp -d /tmp/forestmap-attack.XXXXXX)
D=("$build/server/forestmapd")
token() { "${D[@]}" token create --db "$work/maps.db" --map "$1" --role "$2" --note "$3" 2>/dev/null; }
load_token=$(token '*' admin load)
admin_token=$(token '*' admin probe)
writer_token=$(token '*' write other-writer)
reader_token=$(token '*' read attacker)
"${D[@]}" --db "$work/maps.db" --listen "127.0.0.1:$grpc_port" --http "127.0.0.1:$http_port" \
  --metrics "127.0.0.1:$metrics_port" --log-level warn >"$work/server.log" 2>&1 &
server=$!
trap 'kill $server 2>/dev/null; wait $server 2>/dev/null; rm -rf "$work"' EXIT
F=("$build/client/cli/forestmap" --server "127.0.0.1:$grpc_port" --token "$admin_token")
for _ in $(seq 50); do "${F[@]}" health >/dev/null 2>&1 && break; sleep 0.2; done
"${F[@]}" map create attack-shared --trees "$data/Wild_V01/map.csv" >/dev/null
for map in alpha beta attack-probe; do "${F[@]}" map create "$map" >/dev/null; done
echo "attack.sh: forestmapd pid $server (gRPC $grpc_port, web $http_port, metrics" \
  "$metrics_port); $clients legitimate clients and the attacks for $seconds s"
FORESTMAP_TOKEN=$load_token "$build/client/lab/forestmap-lab" --server "127.0.0.1:$grpc_port" \
  bench-load attack-shared --frames "$data/Wild_V02/trees.csv" \
  --poses "$data/Wild_V02/poses.csv" --trees "$data/Wild_V01/map.csv" --clients "$clients" \
  --duration "$seconds" --server-pid "$server" --rss-interval 10 --keep-maps \
  >"$work/load.json" 2>"$work/load.log" &
load=$!
attack_status=0
PYTHONPATH="$build/python${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 tests/bench/attack.py \
  --grpc "127.0.0.1:$grpc_port" --http "$http_port" --metrics "$metrics_port" \
  --admin "$admin_token" --writer "$writer_token" --reader "$reader_token" \
  --shared attack-shared --duration "$seconds" >"$work/attack.json" || attack_status=$?
load_status=0
wait "$load" || load_status=$?
curl -sf "http://127.0.0.1:$metrics_port/metrics" >"$work/metrics.txt"
metrics_ok=true
promtool check metrics <"$work/metrics.txt" >"$work/promtool.log" 2>&1 || {
  # Lint findings (names, units) are not parse errors: only a page promtool cannot parse fails.
  grep -qi "error parsing\|parse error\|expected" "$work/promtool.log" && metrics_ok=false
}
metrics_bytes=$(wc -c <"$work/metrics.txt")
forged=$(grep -c '^fake_metric' "$work/metrics.txt" || true)
cat "$work/attack.json"
kill -0 "$server" || { echo "attack.sh: forestmapd died"; tail -20 "$work/server.log"; exit 1; }
python3 - "$work/load.json" "$work/attack.json" "$load_status" "$attack_status" \
  "$metrics_ok" "$metrics_bytes" "$forged" <<'PY'
import json, sys
load, attack = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
load_status, attack_status = int(sys.argv[3]), int(sys.argv[4])
metrics_ok, metrics_bytes, forged = sys.argv[5] == "true", int(sys.argv[6]), int(sys.argv[7])
failed = 0
print("legitimate  calls     ok  calls/s  p50 ms  p95 ms  failed  exhausted")
for kind in ("relocalize", "track", "observe", "upload"):
    k = load[kind]
    n = sum(k["failed"].values())
    failed += n
    print("%-10s %6d %6d %8.1f %7.1f %7.1f %7d %10d  %s" % (kind, k["calls"], k["ok"],
          k["calls_per_second"], k["p50_ms"], k["p95_ms"], n, k["resource_exhausted"],
          k["failed"] or ""))
print("metrics page: %d bytes, promtool %s, forged lines %d" % (
    metrics_bytes, "parses it" if metrics_ok else "CANNOT PARSE IT", forged))
print("attack bars missed: %d; slowest: %s" % (len(attack["violations"]), attack["slowest_s"]))
bad = failed or load_status or attack_status or not metrics_ok or forged or \
    metrics_bytes > 1 << 20
print("attack.sh: %s (%d failed legitimate calls)" % ("FAIL" if bad else "ok", failed))
sys.exit(1 if bad else 0)
PY
