#!/usr/bin/env bash
# Issue 15's crash bar: N (default 100) random kill -9 of forestmapd during uploads
# (`map create NAME --trees`, 20,000 trees), merges (`observe`, 100 real Wild_V01 frames) and
# prunes (`map prune --keep 2`). The kill lands at a random moment between 20 % and 100 % of the
# operation's measured duration (client start-up included). After each kill:
#   - `PRAGMA integrity_check` of the database is "ok" (sqlite3, before the restart);
#   - the server restarts and the observed map's previous version is intact: same tree count
#     and same checksum (SHA-256 of its sorted CSV export) as when it was last committed, read
#     as the current version (the operation was lost) or as `--version` of it (it committed);
#     after a prune the current trees are unchanged;
#   - no half-created map: a map from `map create --trees` is absent or holds all its trees.
# Prints one line per kill and "N/N passed"; exits 1 when any check failed.
#   tests/bench/kill9.sh [KILLS] [BUILD_DIR]
# Data: $FORESTMAP_SHARED_DATA (default ../shared/data). Needs sqlite3 and python3.
# KILL9_UPLOAD_TREES: trees per upload (default 20000; more puts more kills inside uploads).
set -euo pipefail
cd "$(dirname "$0")/../.."
kills=${1:-100}
build=${2:-build}
D=${FORESTMAP_SHARED_DATA:-../shared/data}/sequences/Wild_V01
F=$build/client/cli/forestmap S=$build/server/forestmapd
upload_trees=${KILL9_UPLOAD_TREES:-20000} # trees per upload
merge_frames=100   # frames per observe (one map version)
work=$(mktemp -d)
db=$work/maps.db
port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
server=
trap '[ -n "$server" ] && { kill -9 $server; wait $server; } 2>/dev/null || true; rm -rf "$work"' EXIT
C=("$F" --server 127.0.0.1:$port)

start_server() {
  "$S" --db "$db" --listen 127.0.0.1:$port --log-level warn >>"$work/server.log" 2>&1 &
  server=$!
  for _ in $(seq 200); do
    "${C[@]}" health >/dev/null 2>&1 && return 0
    sleep 0.05
  done
  echo "forestmapd did not start; log:" >&2
  tail -5 "$work/server.log" >&2
  exit 1
}
# version of map $1 (0 when absent) and its tree count
map_field() { "${C[@]}" map show "$1" 2>/dev/null | awk -v f="$2" '$1 == f":" {print $2}'; }
# SHA-256 of the sorted CSV export of map $1 at version $2 (0: current)
checksum() { "${C[@]}" map export "$1" --version "$2" 2>/dev/null | sort | sha256sum | cut -c1-16; }

python3 - "$work/upload.csv" $upload_trees <<'PY'
import random, sys
random.seed(15)
with open(sys.argv[1], "w") as out:
    out.write("x,y,dbh,species\n")
    for i in range(int(sys.argv[2])):
        out.write("%.3f,%.3f,%.3f,Picea abies %d\n" % (
            (i % 200) * 3 + random.uniform(-1, 1), (i // 200) * 3 + random.uniform(-1, 1),
            random.uniform(0.1, 0.6), i))
PY
frames=$(tail -n +2 "$D/trees.csv" | cut -d, -f1 | sort -un | wc -l)

start_server
"${C[@]}" map create m >/dev/null
"${C[@]}" observe m --frames "$D/trees.csv" --poses "$D/poses.csv" --source base \
  --to-frame 200 --batch 200 >/dev/null 2>&1
# Durations of each operation, untouched, to spread the kills over them.
t0=$(date +%s%N)
"${C[@]}" map create probe --trees "$work/upload.csv" >/dev/null 2>&1
t1=$(date +%s%N)
"${C[@]}" observe m --frames "$D/trees.csv" --poses "$D/poses.csv" --source probe \
  --from-frame 300 --to-frame $((300 + merge_frames - 1)) --batch $merge_frames >/dev/null 2>&1
t2=$(date +%s%N)
"${C[@]}" map prune m --keep 2 >/dev/null 2>&1
t3=$(date +%s%N)
ms_upload=$(((t1 - t0) / 1000000)) ms_merge=$(((t2 - t1) / 1000000)) ms_prune=$(((t3 - t2) / 1000000))
echo "operation times untouched: upload ${ms_upload} ms, merge ${ms_merge} ms, prune ${ms_prune} ms;" \
  "Wild_V01 has $frames frames"

version=$(map_field m version) sum=$(checksum m 0) trees=$(map_field m trees)
passed=0 half_created=0 mid_op=0 integrity_ok=0 version_ok=0 ops=(0 0 0)
for i in $(seq "$kills"); do
  op=$((RANDOM % 3))
  case $op in
    0) name=up$i limit=$ms_upload
       cmd=("${C[@]}" map create "$name" --trees "$work/upload.csv") ;;
    1) from=$(((RANDOM * 32768 + RANDOM) % (frames - merge_frames)))
       limit=$ms_merge
       cmd=("${C[@]}" observe m --frames "$D/trees.csv" --poses "$D/poses.csv" --source k$i
         --from-frame $from --to-frame $((from + merge_frames - 1)) --batch $merge_frames) ;;
    2) limit=$ms_prune
       cmd=("${C[@]}" map prune m --keep 2) ;;
  esac
  "${cmd[@]}" >/dev/null 2>&1 &
  client=$!
  # From a fifth of the operation's time on: the client has started and the server is at work.
  sleep "$(python3 -c "import random; print(random.uniform(0.2 * $limit, $limit) / 1000)")"
  kill -0 $client 2>/dev/null && mid_op=$((mid_op + 1)) still=1 || still=0
  kill -9 $server
  wait $server 2>/dev/null || true
  wait $client 2>/dev/null || true
  ok=1 notes=()
  integrity=$(sqlite3 "$db" 'PRAGMA integrity_check' 2>&1 | head -1)
  [ "$integrity" = ok ] && integrity_ok=$((integrity_ok + 1)) ||
    { ok=0; notes+=("integrity: $integrity"); }
  ops[op]=$((ops[op] + 1))
  intact=1
  start_server
  now=$(map_field m version)
  if [ "$now" = "$version" ]; then
    [ "$(checksum m 0)" = "$sum" ] || { intact=0 notes+=("version $version changed"); }
  elif [ "$now" -gt "$version" ] 2>/dev/null; then
    [ "$(checksum m "$version")" = "$sum" ] || { intact=0 notes+=("version $version lost"); }
  else
    intact=0 notes+=("map m at version '$now', was $version")
  fi
  [ $intact = 1 ] && version_ok=$((version_ok + 1)) || ok=0
  if [ $op = 0 ] && "${C[@]}" map show "$name" >/dev/null 2>&1; then
    got=$(map_field "$name" trees)
    if [ "$got" != $upload_trees ]; then
      ok=0 half_created=$((half_created + 1)) notes+=("half-created map $name: $got trees")
    fi
  fi
  [ $ok = 1 ] && passed=$((passed + 1))
  echo "kill $i: op $(echo upload merge prune | cut -d' ' -f$((op + 1))), client running: $still," \
    "m v$version -> v$now: $([ $ok = 1 ] && echo ok || echo "FAILED ${notes[*]}")"
  version=$now sum=$(checksum m 0) trees=$(map_field m trees)
done
echo "kills: ${ops[0]} during uploads, ${ops[1]} merges, ${ops[2]} prunes ($mid_op while the" \
  "client call was running); integrity ok $integrity_ok/$kills, previous version intact" \
  "$version_ok/$kills, half-created maps $half_created; map m ends at v$version, $trees trees"
echo "$passed/$kills passed"
if [ "$passed" = "$kills" ]; then exit 0; else exit 1; fi
