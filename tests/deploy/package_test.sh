#!/usr/bin/env bash
# The Debian packages on this machine, as an operator gets them: builds forestmapd_*.deb and
# forestmap_*.deb from BUILD_DIR (cpack), installs them with apt-get offline (every dependency is
# already here: the build machine's libraries), checks what they put where (user, state directory,
# conffile, unit pointing at /usr/bin/forestmapd, `systemd-analyze verify`), runs the INSTALLED
# forestmapd as the package's user on a loopback port, checks `forestmap health` and the
# relocalization of a real Oxford_Stein frame against its uploaded map (truth: poses.csv), then
# removes (maps and user kept) and purges (everything gone).
# It installs into the real system: it refuses to run where the packages are already installed,
# holds a lock against concurrent runs, and purges what it installed even when it fails.
# Usage: package_test.sh BUILD_DIR DATA_DIR
set -euo pipefail
build="$(cd "$1" && pwd)"
data="$2"
frame=500          # an Oxford_Stein frame (103 trees) whose truth pose is in poses.csv
tolerance_m=0.5    # position error accepted against that truth

fail() { echo "package_test: $*" >&2; exit 1; }
[ "$(id -u)" -eq 0 ] || fail "must run as root (it installs the packages with apt-get)"
[ -f "$data/sequences/Oxford_Stein/map.csv" ] || fail "no real data in $data (../shared/data)"
exec 9>/var/lock/forestmap-package-test.lock
flock 9
installed() { dpkg-query -W -f='${db:Status-Status}' "$1" 2>/dev/null | grep -qv '^not-installed$'; }
for package in forestmapd forestmap; do
  ! installed "$package" || fail "package $package is installed on this machine; the test " \
    "installs and purges its own: 'apt-get purge $package' first"
  [ ! -e "/usr/bin/$package" ] || fail "/usr/bin/$package exists (cmake --install --prefix /usr?)" \
    "and would be replaced, then deleted: remove it first"
done

work="$(mktemp -d /tmp/forestmap-package-XXXXXX)"
server=""
cleanup() {
  [ -z "$server" ] || { kill "$server" 2>/dev/null || true; wait "$server" 2>/dev/null || true; }
  if installed forestmapd || installed forestmap; then
    DEBIAN_FRONTEND=noninteractive apt-get purge -y -qq forestmapd forestmap >/dev/null 2>&1 || true
  fi
  rm -rf "$work"
}
trap cleanup EXIT

echo "== cpack"
cpack --config "$build/CPackConfig.cmake" -B "$work/packages" >"$work/cpack.log" 2>&1 ||
  { cat "$work/cpack.log"; fail "cpack failed"; }
debs=("$work"/packages/forestmapd_*.deb "$work"/packages/forestmap_*.deb)
[ -f "${debs[0]}" ] && [ -f "${debs[1]}" ] || fail "cpack made no forestmapd/forestmap .deb: $(ls "$work/packages")"
depends="$(dpkg-deb -f "${debs[0]}" Depends)"
echo "forestmapd Depends: $depends"
depends_names="$(tr ',' '\n' <<<"$depends" | sed 's/^ *//; s/[ (].*//')"
for library in libc6 libgrpc++1.51 libsqlite3-0 libpq5 adduser; do
  grep -qxF "$library" <<<"$depends_names" || fail "forestmapd's Depends lack $library"
done

echo "== apt-get install (offline: any download would go to a closed loopback port)"
DEBIAN_FRONTEND=noninteractive apt-get install -y -q -o Acquire::http::Proxy=http://127.0.0.1:9 \
  -o Acquire::https::Proxy=http://127.0.0.1:9 "${debs[@]}" \
  >"$work/install.log" 2>&1 || { cat "$work/install.log"; fail "apt-get install failed"; }
for path in /usr/bin/forestmapd /usr/bin/forestmap /etc/forestmapd/forestmapd.env \
            /usr/lib/systemd/system/forestmapd.service \
            /usr/lib/systemd/system/forestmapd.service.d/forestmapd-user.conf; do
  [ -e "$path" ] || fail "$path not installed"
done
uid="$(id -u forestmapd)" || fail "no user forestmapd"
[ "$uid" -lt 1000 ] || fail "forestmapd is not a system user (uid $uid)"
[ "$(stat -c '%U %a' /var/lib/forestmapd)" = "forestmapd 700" ] ||
  fail "/var/lib/forestmapd is $(stat -c '%U %a' /var/lib/forestmapd), not forestmapd 700"
for conffile in /etc/forestmapd/forestmapd.env /etc/forestmapd/forestmapd.conf; do
  dpkg-query -W -f='${Conffiles}' forestmapd | grep -q " $conffile " ||
    fail "$conffile is not a conffile"
done
[ "$(stat -c %G:%a /etc/forestmapd/forestmapd.conf)" = forestmapd:640 ] ||
  fail "/etc/forestmapd/forestmapd.conf is not readable by the service's group only"
grep -qE '^ExecStart=/usr/bin/forestmapd( |$)' /usr/lib/systemd/system/forestmapd.service ||
  fail "the installed unit does not start /usr/bin/forestmapd"
output="$(systemd-analyze verify forestmapd.service 2>&1 || echo "systemd-analyze verify failed")"
[ -z "$output" ] || fail "installed unit: $output"

echo "== the installed forestmapd, as user forestmapd"
cd /var/lib/forestmapd
setpriv --reuid=forestmapd --regid=forestmapd --clear-groups \
  /usr/bin/forestmapd --db /var/lib/forestmapd/package-test.db --listen 127.0.0.1:0 \
  >"$work/server.log" 2>&1 &
server=$!
port=""
for _ in $(seq 100); do
  port="$(sed -n 's/.*serving on 127\.0\.0\.1:\([0-9]*\),.*/\1/p' "$work/server.log")"
  [ -z "$port" ] && kill -0 "$server" 2>/dev/null || break
  sleep 0.1
done
[ -n "$port" ] || { cat "$work/server.log"; fail "forestmapd did not start"; }
client=(/usr/bin/forestmap --server "127.0.0.1:$port")
"${client[@]}" health || fail "forestmap health: not SERVING"
sequence="$data/sequences/Oxford_Stein"
"${client[@]}" map create stein --trees "$sequence/map.csv"
awk -F, -v f="$frame" 'NR == 1 || $1 == f' "$sequence/trees.csv" >"$work/frame.csv"
answer="$("${client[@]}" relocalize stein --trees "$work/frame.csv")"
echo "frame $frame: $answer"
field() { sed -n "s/.*\"$1\":\([^,}]*\).*/\1/p" <<<"$answer"; }
[ "$(field status)" = '"localized"' ] || fail "frame $frame not localized"
truth="$(awk -F, -v f="$frame" '$1 == f { print $3, $4 }' "$sequence/poses.csv")"
awk -v t="$truth" -v x="$(field x)" -v y="$(field y)" -v tol="$tolerance_m" 'BEGIN {
  split(t, p, " "); e = sqrt((x - p[1])^2 + (y - p[2])^2)
  printf "position error %.3f m (tolerance %.1f m)\n", e, tol; exit !(e <= tol) }' ||
  fail "frame $frame relocalized away from its truth pose"
kill "$server"
wait "$server" || fail "forestmapd did not stop cleanly on SIGTERM"
server=""

echo "== apt-get remove: the maps, the user and the configuration stay"
DEBIAN_FRONTEND=noninteractive apt-get remove -y -qq forestmapd forestmap >/dev/null
[ ! -e /usr/bin/forestmapd ] && [ ! -e /usr/bin/forestmap ] || fail "remove left the programs"
[ -f /var/lib/forestmapd/package-test.db ] || fail "remove deleted the maps"
[ -f /etc/forestmapd/forestmapd.env ] || fail "remove deleted the configuration"
id forestmapd >/dev/null || fail "remove deleted the user"

echo "== apt-get purge: nothing left"
DEBIAN_FRONTEND=noninteractive apt-get purge -y -qq forestmapd forestmap >/dev/null
for path in /var/lib/forestmapd /etc/forestmapd /usr/lib/systemd/system/forestmapd.service \
            /usr/lib/systemd/system/forestmapd.service.d; do
  [ ! -e "$path" ] || fail "purge left $path"
done
! id forestmapd >/dev/null 2>&1 || fail "purge left the user forestmapd"
! getent group forestmapd >/dev/null || fail "purge left the group forestmapd"
! installed forestmapd && ! installed forestmap || fail "dpkg still lists the packages"
echo "package_test: passed"
