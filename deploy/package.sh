#!/usr/bin/env bash
# Builds the Debian packages forestmapd and forestmap (CPack; cmake/packaging.cmake) and prints
# their paths: installs what building them needs and nothing of the tests (deploy/install-deps.sh
# --product; skipped when FORESTMAP_NO_INSTALL_DEPS=1, as in deploy/Dockerfile, whose build stage
# installs the same list), then a
# Release build of the two programs only (no tests, no lab) in BUILD_DIR (default build-package),
# then cpack into BUILD_DIR/packages. Install them with
#   apt-get install ./build-package/packages/forestmapd_*.deb ./build-package/packages/forestmap_*.deb
set -euo pipefail
cd "$(dirname "$0")/.."
build="${1:-build-package}"
[ "${FORESTMAP_NO_INSTALL_DEPS:-0}" = 1 ] || bash deploy/install-deps.sh --product
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release -DFORESTMAP_BUILD_TESTS=OFF \
  -DFORESTMAP_BUILD_LAB=OFF >/dev/null
cmake --build "$build" -j"$(nproc)"
rm -rf "$build/packages"
cpack --config "$build/CPackConfig.cmake" -B "$build/packages" >/dev/null
ls "$build"/packages/*.deb
