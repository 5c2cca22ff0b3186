#!/usr/bin/env bash
# Command 2 of the README: installs dependencies, builds the product in Release (build) and runs
# its end-to-end, packaging and lint tests (CTest), then builds the threaded code with
# ThreadSanitizer and runs those tests (build-tsan), then every unit test with AddressSanitizer
# and UndefinedBehaviorSanitizer (build-asan), then every libFuzzer target for 30 s (build-fuzz).
# Each unit test runs once, in the sanitizer build (the Release build leaves them out:
# FORESTMAP_UNIT_TESTS=OFF). Tests read the real forest data from ../shared/data (CI always has
# it; under CI=true a test that needs it fails instead of skipping).
set -euo pipefail
cd "$(dirname "$0")/.."
# The sanitizer builds: -O1 (the sanitizers' own advice: reports stay exact, the build is fast).
SANITIZER_FLAGS=(-DCMAKE_BUILD_TYPE=Release "-DCMAKE_CXX_FLAGS_RELEASE=-O1 -DNDEBUG")
bash deploy/install-deps.sh
# Ninja for new build folders (an existing one keeps the generator it was made with).
export CMAKE_GENERATOR="${CMAKE_GENERATOR:-Ninja}"
echo "test: the product in Release and its end-to-end, packaging and lint tests (build)"
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DFORESTMAP_UNIT_TESTS=OFF >/dev/null
cmake --build build -j"$(nproc)"
ctest --test-dir build --output-on-failure -j"$(nproc)" --timeout 1200

echo "test: ThreadSanitizer build of the threaded tests (build-tsan; see tests/CMakeLists.txt)"
# Debian's libraries are not instrumented: reports from inside them are ignored; any report in
# our code fails the run (halt_on_error; TSan's exit code 66).
export TSAN_OPTIONS="ignore_noninstrumented_modules=1 halt_on_error=1 second_deadlock_stack=1 suppressions=$PWD/tests/tsan.supp"
cmake -S . -B build-tsan "${SANITIZER_FLAGS[@]}" -DFORESTMAP_SANITIZE=thread >/dev/null
cmake --build build-tsan -j"$(nproc)" --target threaded_tests
# $(nproc) programs at a time, each one's output printed when it ends.
tsan_run() { out=$("$1" --gtest_brief=1 2>&1) && echo "passed: $1" || { echo "$out"; echo "FAILED under TSan: $1"; return 1; }; }
export -f tsan_run
if grep . build-tsan/threaded_tests.txt | xargs -P "$(nproc)" -I{} bash -c 'tsan_run {}'; then
  echo "ThreadSanitizer: every program passed"
else
  echo "ThreadSanitizer: FAILED (above)"
  exit 1
fi

echo "test: AddressSanitizer + UndefinedBehaviorSanitizer build of the unit tests (build-asan)"
# Memory errors, leaks and undefined behaviour in our code fail the run (Debian's libraries are
# not instrumented; their allocations are still checked for leaks and overflows by ASan).
export ASAN_OPTIONS="halt_on_error=1 detect_leaks=1 detect_stack_use_after_return=1"
export UBSAN_OPTIONS="halt_on_error=1 print_stacktrace=1"
export LSAN_OPTIONS="suppressions=$PWD/tests/lsan.supp"
cmake -S . -B build-asan "${SANITIZER_FLAGS[@]}" -DFORESTMAP_SANITIZE=address,undefined >/dev/null
cmake --build build-asan -j"$(nproc)" --target unit_tests
ctest --test-dir build-asan -L unit --output-on-failure -j"$(nproc)" --timeout 1200

echo "test: libFuzzer targets, 30 s each (build-fuzz, clang; see tests/fuzz/run.sh)"
# Only the fuzz targets and what they link (client/io, the protos, server/grpc/validation.cc,
# server/http's routes and server/ops/metrics.cc).
cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_C_COMPILER=clang \
  -DCMAKE_CXX_COMPILER=clang++ -DFORESTMAP_FUZZ=ON -DFORESTMAP_BUILD_TESTS=OFF >/dev/null
cmake --build build-fuzz -j"$(nproc)" --target fuzz_targets
# A fixed seed: this step checks that the corpus and a known sequence of mutations pass, the same
# on every machine; exploration is the long runs with a new seed each (tests/fuzz/run.sh, docs/development.md "Fuzzing").
FUZZ_SEED=1 bash tests/fuzz/run.sh build-fuzz 30 "$(nproc)"
