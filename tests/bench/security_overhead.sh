#!/usr/bin/env bash
# What tokens, TLS and the per-RPC log line cost: bench-server (Wild_V02 frames relocalized in the
# Wild_V01 map, 8 client threads) against forestmapd open/plaintext, then with a token required,
# then with a token over TLS (a self-signed certificate made here). Run from the repository root
# after building forestmapd, forestmap and forestmap-lab in build/. Usage: tests/bench/security_overhead.sh [REQUESTS]
set -euo pipefail
requests=${1:-3000}
D=${FORESTMAP_SHARED_DATA:-../shared/data}/sequences
S=build/server/forestmapd
F=build/client/cli/forestmap L=build/client/lab/forestmap-lab
work=$(mktemp -d)
server_pid=
cleanup() { [ -n "$server_pid" ] && kill "$server_pid" 2>/dev/null; wait 2>/dev/null; rm -rf "$work"; }
trap cleanup EXIT

serve() {  # serve PORT [extra flags]: starts forestmapd on $work/maps.db, waits until it listens
  local port=$1; shift
  "$S" --db "$work/maps.db" --listen 127.0.0.1:$port "$@" 2>"$work/server.log" &
  server_pid=$!
  for _ in $(seq 50); do grep -q "serving on" "$work/server.log" 2>/dev/null && return; sleep 0.1; done
  grep -q "serving on" "$work/server.log" || { cat "$work/server.log"; exit 1; }
}
stop() { kill "$server_pid"; wait "$server_pid" || true; server_pid=; }
bench() {  # bench LABEL [client flags]
  local label=$1; shift
  echo "== $label"
  "$L" --server 127.0.0.1:$port "$@" bench-server venman --frames "$D/Wild_V02/trees.csv" \
    --concurrency 8 --requests "$requests" 2>&1 | tail -3
}

port=50191
"$S" --help >/dev/null
serve $port
"$F" --server 127.0.0.1:$port map create venman --trees "$D/Wild_V01/map.csv" >/dev/null
bench "open, plaintext (the per-RPC log line only)"
stop

token=$("$S" token create --db "$work/maps.db" --map venman --role read 2>/dev/null)
serve $port
bench "token required (read on venman), plaintext" --token "$token"
stop

openssl req -x509 -newkey rsa:2048 -nodes -days 1 -subj /CN=bench \
  -addext subjectAltName=IP:127.0.0.1 -keyout "$work/key.pem" -out "$work/cert.pem" 2>/dev/null
serve $port --tls-cert "$work/cert.pem" --tls-key "$work/key.pem"
bench "token required, TLS" --token "$token" --tls-ca "$work/cert.pem"
stop
