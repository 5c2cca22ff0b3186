#!/usr/bin/env bash
# Fails (exit 1) listing every C++ file that differs from .clang-format; run from anywhere.
# Fix with: clang-format -i $(git ls-files '*.h' '*.cc')
set -euo pipefail
cd "$(dirname "$0")/../.."
if git rev-parse --is-inside-work-tree >/dev/null 2>&1; then
  mapfile -t files < <(git ls-files '*.h' '*.cc')
else
  mapfile -t files < <(find algorithms client proto server storage tests -name '*.h' -o -name '*.cc')
fi
present=()
for f in "${files[@]}"; do [ -f "$f" ] && present+=("$f"); done
# One clang-format for every file; each violation is a line "FILE:LINE:COL: error: ...".
status=0
report=$(clang-format --dry-run --Werror "${present[@]}" 2>&1 >/dev/null) || status=$?
mapfile -t bad < <(sed -n 's/^\([^:]*\):[0-9]*:[0-9]*: error: .*/\1/p' <<<"$report" | sort -u)
if [ "$status" -ne 0 ] && [ ${#bad[@]} -eq 0 ]; then
  echo "$report"
  echo "check_format: clang-format failed (exit $status)"
  exit 1
fi
if [ ${#bad[@]} -gt 0 ]; then
  printf 'not formatted: %s\n' "${bad[@]}"
  echo "check_format: ${#bad[@]} of ${#files[@]} files differ from .clang-format"
  exit 1
fi
echo "check_format: ${#files[@]} files formatted"
