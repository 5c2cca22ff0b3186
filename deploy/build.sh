#!/usr/bin/env bash
# Installs the Debian packages (deploy/install-deps.sh), then configures and builds ForestMap in
# ./build (Release). Extra arguments are passed to `cmake --build`, e.g. `--target forestmapd`.
set -euo pipefail
cd "$(dirname "$0")/.."
bash deploy/install-deps.sh
# Ninja for new build folders (an existing one keeps the generator it was made with).
export CMAKE_GENERATOR="${CMAKE_GENERATOR:-Ninja}"
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc)" "$@"
