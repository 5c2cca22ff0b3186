#!/usr/bin/env bash
# Time of `forestmap compare` on generated inventories (the new-user trial's 30k / 60k / 300k
# case, which was quadratic): a random stand of N trees (a density of ~400 trees/ha, DBH 0.1-0.6
# m) against itself jittered by 0.2 m with 5 % of trees dropped on each side.
#   tests/bench/compare.sh [N ...]        (after building forestmap; default 30000 300000 1000000)
# Prints one markdown row per N: wall and CPU seconds (includes reading both CSVs), links.
set -euo pipefail
cd "$(dirname "$0")/../.."
F=build/client/cli/forestmap
DIR=$(mktemp -d)
trap 'rm -rf "$DIR"' EXIT
SIZES=("$@")
[ ${#SIZES[@]} -eq 0 ] && SIZES=(30000 300000 1000000)
echo "| trees | wall s | CPU s | linked | completeness |"
echo "|---|---|---|---|---|"
for n in "${SIZES[@]}"; do
  python3 - "$n" "$DIR" <<'PY'
import math, random, sys
n, out = int(sys.argv[1]), sys.argv[2]
rng = random.Random(n)              # fixed seed per size
side = math.sqrt(n / 0.04)          # m: 0.04 trees per m^2 = 400 / ha
with open(out + "/r.csv", "w") as r, open(out + "/d.csv", "w") as d:
    r.write("id,x,y,dbh\n"); d.write("id,x,y,dbh\n")
    for i in range(n):
        x, y, dbh = rng.uniform(0, side), rng.uniform(0, side), rng.uniform(0.1, 0.6)
        if rng.random() > 0.05:
            r.write("%d,%.3f,%.3f,%.3f\n" % (i, x, y, dbh))
        if rng.random() > 0.05:
            d.write("%d,%.3f,%.3f,%.3f\n" % (i, x + rng.gauss(0, 0.2), y + rng.gauss(0, 0.2),
                                             dbh + rng.gauss(0, 0.02)))
PY
  /usr/bin/time -f "%e %U %S" -o "$DIR/time" "$F" compare "$DIR/d.csv" --reference "$DIR/r.csv" \
    --json >"$DIR/out.json"
  read -r wall user sys <"$DIR/time"
  python3 - "$n" "$wall" "$user" "$sys" "$DIR/out.json" <<'PY'
import json, sys
n, wall, user, sys_s, path = sys.argv[1:]
r = json.load(open(path))
print("| %s | %s | %.2f | %d | %.1f %% |" % (n, wall, float(user) + float(sys_s), r["linked"],
                                              100 * r["completeness"]))
PY
done
