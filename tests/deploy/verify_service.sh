#!/usr/bin/env bash
# Installs the build into a temporary prefix (`cmake --install`), checks that the programs are
# there and run, that the installed unit's ExecStart is the installed forestmapd, and verifies the
# unit with `systemd-analyze verify` (which checks that the binary exists).
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
unit="$prefix/lib/systemd/system/forestmapd.service"
test -f "$unit" || { echo "cmake --install did not install forestmapd.service"; exit 1; }
# ExecStart names the forestmapd of this install's prefix (cmake/install_unit.cmake).
grep -q "^ExecStart=$prefix/bin/forestmapd " "$unit" ||
  { echo "the installed unit does not start $prefix/bin/forestmapd: $(grep ^ExecStart "$unit")"; exit 1; }
# verify prints problems as warnings on stderr but only some make it fail: fail on any output.
output="$(systemd-analyze verify "$unit" 2>&1 || echo "systemd-analyze verify failed")"
if [ -n "$output" ]; then
  echo "$output"
  exit 1
fi
echo "forestmapd.service verified; installed: $(ls "$prefix/bin" | tr '\n' ' ')"
