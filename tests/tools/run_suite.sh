#!/usr/bin/env bash
# Runs one GoogleTest suite for CTest (tests/discover_suites.cmake): PROGRAM --gtest_filter=SUITE.*
# with its output as it comes. Exits 77 (the tests' SKIP_RETURN_CODE) when the suite passed with
# every test skipped; else with the program's status, so a failing test is never hidden by a
# skipped one beside it.
# Usage: tests/tools/run_suite.sh PROGRAM SUITE
set -uo pipefail
out=$(mktemp)
trap 'rm -f "$out"' EXIT
"$1" "--gtest_filter=$2.*" 2>&1 | tee "$out"
status=${PIPESTATUS[0]}
if [ "$status" -eq 0 ] && grep -q '^\[  PASSED  \] 0 tests' "$out" && grep -q '^\[  SKIPPED \]' "$out"; then
  exit 77
fi
exit "$status"
