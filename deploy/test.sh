#!/usr/bin/env bash
# Command 2 of the README: installs dependencies, builds everything and runs every test.
# Tests read the real forest data from ../shared/data when it is there (CI always has it).
set -euo pipefail
cd "$(dirname "$0")/.."
bash deploy/build.sh
ctest --test-dir build --output-on-failure -j"$(nproc)" --timeout 1200
