#!/usr/bin/env bash
# Command 2 of the README: installs dependencies, builds everything and runs every test, then
# builds the threaded code (storage, server, loopback integration tests) with ThreadSanitizer and
# runs those tests again. Tests read the real forest data from ../shared/data (CI always has it;
# under CI=true a test that needs it fails instead of skipping).
set -euo pipefail
cd "$(dirname "$0")/.."
bash deploy/build.sh
ctest --test-dir build --output-on-failure -j"$(nproc)" --timeout 1200

echo "test: ThreadSanitizer build of the storage, server and integration tests (build-tsan)"
cmake -S . -B build-tsan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DFORESTMAP_SANITIZE=thread >/dev/null
cmake --build build-tsan -j"$(nproc)" --target threaded_tests
# Debian's gRPC, Protobuf and SQLite are not instrumented: their own synchronisation is invisible
# to TSan, so reports from inside them are ignored (ignore_noninstrumented_modules); every report
# in our code fails the run (halt_on_error, exitcode).
export TSAN_OPTIONS="ignore_noninstrumented_modules=1 halt_on_error=1 exitcode=66 second_deadlock_stack=1 suppressions=$PWD/tests/tsan.supp"
ctest --test-dir build-tsan --output-on-failure -j"$(nproc)" --timeout 1200 -L 'storage|server|integration'
