#!/usr/bin/env bash
# Installs the build into a temporary prefix (`cmake --install`), checks that the programs are
# there and run (--help, --version), that the installed unit's ExecStart is the installed
# forestmapd, and verifies the unit with `systemd-analyze verify` (which checks that the binary
# exists). The unit passes no settings (forestmapd reads /etc/forestmapd/forestmapd.conf), reloads
# with SIGHUP and does not restart on a usage error.
# Usage: verify_service.sh BUILD_DIR [PROGRAM...]   (default: forestmapd forestmap)
set -euo pipefail
build="$1"
shift
programs=("$@")
[ ${#programs[@]} -gt 0 ] || programs=(forestmapd forestmap)
command -v systemd-analyze >/dev/null || { echo "systemd-analyze missing (Debian: systemd)"; exit 1; }
prefix="$(mktemp -d /tmp/forestmap-install-XXXXXX)"
trap 'rm -rf "$prefix"' EXIT
cmake --install "$build" --prefix "$prefix" >/dev/null
for binary in "${programs[@]}"; do
  test -x "$prefix/bin/$binary" || { echo "cmake --install did not install $binary"; exit 1; }
  "$prefix/bin/$binary" --help >/dev/null
done
version="$("$prefix/bin/forestmapd" --version)"
[[ "$version" =~ ^forestmapd\ [0-9]+\.[0-9]+\.[0-9]+\ \(commit\ ([0-9a-f]{12}(-dirty)?|unknown),\ [A-Za-z]+\)$ ]] ||
  { echo "forestmapd --version printed '$version'"; exit 1; }
unit="$prefix/lib/systemd/system/forestmapd.service"
test -f "$unit" || { echo "cmake --install did not install forestmapd.service"; exit 1; }
# ExecStart names the forestmapd of this install's prefix (cmake/install_unit.cmake), with no
# flags; the unit reloads with SIGHUP and does not restart after a usage error.
for line in "^ExecStart=$prefix/bin/forestmapd\$" '^ExecReload=/bin/kill -HUP \$MAINPID$' \
    '^RestartPreventExitStatus=2$'; do
  grep -qE "$line" "$unit" || { echo "the installed unit has no line matching $line"; exit 1; }
done
# verify prints problems as warnings on stderr but only some make it fail: fail on any output.
output="$(systemd-analyze verify "$unit" 2>&1 || echo "systemd-analyze verify failed")"
if [ -n "$output" ]; then
  echo "$output"
  exit 1
fi
echo "forestmapd.service verified; installed: $(ls "$prefix/bin" | tr '\n' ' ')"
