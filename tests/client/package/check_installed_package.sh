#!/usr/bin/env bash
# The client library as an integrator outside the tree gets it: installs BUILD_DIR into a
# temporary prefix (`cmake --install`), then builds consumer.cc against that prefix only, twice:
# with CMake (this folder's CMakeLists.txt: find_package(ForestMap CONFIG), ForestMap::client) and
# with pkg-config (forestmap-client.pc), and runs both.
# Usage: check_installed_package.sh BUILD_DIR
set -euo pipefail
build=$(realpath "$1")
here=$(cd "$(dirname "$0")" && pwd)
work=$(mktemp -d /tmp/forestmap-package-XXXXXX)
trap 'rm -rf "$work"' EXIT
prefix=$work/prefix
cmake --install "$build" --prefix "$prefix" >/dev/null

# check NAME PROGRAM: the trunk's message and the unreachable server's error, as a user reads it.
check() {
  local output
  output=$("$2")
  if ! grep -qx 'tree 1.5 -2.25 0.25' <<<"$output" ||
     ! grep -q '^ListMaps: cannot reach forestmapd at 127.0.0.1:1: ' <<<"$output"; then
    echo "$1: unexpected output:"
    echo "$output"
    exit 1
  fi
  echo "$1: $output" | head -1
}

cmake -S "$here" -B "$work/cmake" -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$prefix" \
  -DCMAKE_FIND_PACKAGE_NO_PACKAGE_REGISTRY=ON >"$work/cmake.log" 2>&1 || {
  cat "$work/cmake.log"
  exit 1
}
cmake --build "$work/cmake" >"$work/build.log" 2>&1 || { cat "$work/build.log"; exit 1; }
check "find_package(ForestMap)" "$work/cmake/consumer"

pc=$(dirname "$(find "$prefix" -name forestmap-client.pc)")
flags=$(PKG_CONFIG_PATH="$pc" pkg-config --cflags --libs forestmap-client)
# shellcheck disable=SC2086  # the flags are words
c++ "$here/consumer.cc" $flags -o "$work/pkg-config-consumer"
check "pkg-config forestmap-client" "$work/pkg-config-consumer"
echo "installed: $(cd "$prefix" && find bin lib -maxdepth 3 -type f | sort | tr '\n' ' ')"
