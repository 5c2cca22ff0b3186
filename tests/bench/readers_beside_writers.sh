#!/usr/bin/env bash
# Writers do not starve readers, through the real server: forestmapd on a temporary database with
# the real Wild_V01 map; READERS clients relocalize Wild_V02 frames in it for SECONDS alone, then
# again for SECONDS beside WRITERS clients that observe frames all along into one other map
# holding the same trees, so that their writes queue for that map (both with `forestmap-lab
# bench-load`, --mix 1,0,0,0 and 0,0,1,0 --observe-into). Prints relocalizations/s and
# latency alone and beside the writers, the ratio, and the writers' calls; fails when the ratio is
# under 0.7, the p95 beside the writers 50 ms or more, or any call failed other than with
# RESOURCE_EXHAUSTED.
#   tests/bench/readers_beside_writers.sh [SECONDS=30] [READERS=40] [WRITERS=20] [PORT]
# Environment: FORESTMAP_BUILD (build dir, default build), FORESTMAP_SHARED_DATA (default
# ../shared/data), FORESTMAPD (the server binary, default the build's), OBSERVE_FRAMES (frames
# per observe, default 3). Without the data it skips
# (exit 77), unless CI=true.
set -euo pipefail
cd "$(dirname "$0")/../.."
seconds=${1:-30} readers=${2:-40} writers=${3:-20}
port=${4:-$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')}
build=${FORESTMAP_BUILD:-build}
data=${FORESTMAP_SHARED_DATA:-../shared/data}/sequences
F=("$build/client/cli/forestmap" --server "127.0.0.1:$port")
L=("$build/client/lab/forestmap-lab" --server "127.0.0.1:$port")
if [ ! -f "$data/Wild_V01/map.csv" ] || [ ! -f "$data/Wild_V02/trees.csv" ]; then
  echo "readers_beside_writers.sh: no Wild_V01/Wild_V02 data under $data"
  [ "${CI:-}" = true ] && exit 1
  exit 77
fi
work=$(mktemp -d /tmp/forestmap-readers.XXXXXX)
"${FORESTMAPD:-$build/server/forestmapd}" --db "$work/maps.db" --listen "127.0.0.1:$port" \
  --log-level warn >"$work/server.log" 2>&1 &
server=$!
writers_pid=
trap 'kill $writers_pid $server 2>/dev/null; wait $server 2>/dev/null; rm -rf "$work"' EXIT
for _ in $(seq 50); do "${F[@]}" health >/dev/null 2>&1 && break; sleep 0.2; done
for map in shared observed; do
  "${F[@]}" map create "$map" --trees "$data/Wild_V01/map.csv" >"$work/create.log" 2>&1 ||
    { cat "$work/create.log" "$work/server.log"; exit 1; }
done
load() {  # load MIX CLIENTS SECONDS PREFIX [ARGS]: bench-load's JSON report on stdout
  "${L[@]}" bench-load shared --frames "$data/Wild_V02/trees.csv" --poses "$data/Wild_V02/poses.csv" \
    --trees "$data/Wild_V01/map.csv" --mix "$1" --clients "$2" --duration "$3" --prefix "$4" \
    --keep-maps "${@:5}" 2>>"$work/lab.log"
}
load 1,0,0,0 "$readers" 5 warmup >/dev/null  # the index is built, the clients' maps created
load 1,0,0,0 "$readers" "$seconds" alone >"$work/alone.json"
load 0,0,1,0 "$writers" "$((seconds + 30))" writers --observe-into observed \
  --observe-frames "${OBSERVE_FRAMES:-3}" >"$work/writers.json" &
writers_pid=$!
sleep 15  # the writers' maps are created and their observes run
load 1,0,0,0 "$readers" "$seconds" beside >"$work/beside.json"
wait "$writers_pid"
writers_pid=
kill -0 "$server" || { echo "readers_beside_writers.sh: forestmapd died"; tail -20 "$work/server.log"; exit 1; }
python3 - "$work" "$readers" "$writers" "$seconds" <<'PY'
import json, sys
work, readers, writers, seconds = sys.argv[1:]
alone = json.load(open(work + "/alone.json"))["relocalize"]
beside = json.load(open(work + "/beside.json"))["relocalize"]
observe = json.load(open(work + "/writers.json"))["observe"]
print("%s relocalizing clients, %s s each; %s observing clients beside them" % (readers, seconds, writers))
print("                     calls/s  p50 ms  p95 ms  p99 ms  failed  exhausted")
for name, k in (("relocalize alone", alone), ("relocalize beside", beside), ("observe (writers)", observe)):
    print("%-19s %9.1f %7.1f %7.1f %7.1f %7d %10d" % (name, k["calls_per_second"], k["p50_ms"],
          k["p95_ms"], k["p99_ms"], sum(k["failed"].values()), k["resource_exhausted"]))
ratio = beside["calls_per_second"] / alone["calls_per_second"]
print("beside / alone: %.2f" % ratio)
bad = []
if ratio < 0.7: bad.append("ratio %.2f < 0.70" % ratio)
if beside["p95_ms"] >= 50: bad.append("p95 %.1f ms >= 50 ms" % beside["p95_ms"])
for name, k in (("alone", alone), ("beside", beside), ("observe", observe)):
    if sum(k["failed"].values()) or k["ok"] == 0: bad.append(name + ": failed calls or none ok")
if bad:
    sys.exit("readers_beside_writers.sh: " + "; ".join(bad))
PY
