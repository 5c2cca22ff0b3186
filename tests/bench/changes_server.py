#!/usr/bin/env python3
"""Scores a map that forestmapd updated from drone passes over a simulated future against the
truth that `forestmap-lab bench-changes --write DIR` wrote (tests/bench/changes_server.sh).

  changes_server.py ORIGINAL.csv UPDATED.csv TRUTH.json

ORIGINAL.csv: the stem map (id or tree_id, x or x_m, y or y_m[, dbh or dbh_m]); UPDATED.csv: `forestmap map export` of the map after
the passes (id,x,y,z,dbh,status,...). Prints one JSON object: the share of felled trees removed,
of live trees wrongly removed, of new trees confirmed (a confirmed tree that is not an original
within 0.5 m), candidates left per real tree and the median error of the DBH growth found."""
import csv
import json
import math
import statistics
import sys


ALIASES = {"id": ("id", "tree_id"), "x": ("x", "x_m"), "y": ("y", "y_m"),
           "dbh": ("dbh", "dbh_m")}


def read(path):
    with open(path, newline="") as f:
        return {int(number(r, "id")): r for r in csv.DictReader(f)}


def number(row, key):
    value = next((row[k] for k in ALIASES.get(key, (key,)) if row.get(k) not in ("", None)), None)
    return float(value) if value is not None else None


original, updated = read(sys.argv[1]), read(sys.argv[2])
truth = json.load(open(sys.argv[3]))
felled = set(truth["felled"])
live = set(original) - felled
max_original = max(original)
confirmed_new = [(number(r, "x"), number(r, "y")) for i, r in updated.items()
                 if i > max_original and r.get("status") == "confirmed"]
cell = {}
for x, y in confirmed_new:
    cell.setdefault((math.floor(x), math.floor(y)), []).append((x, y))


def near(x, y):
    return any(math.hypot(x - a, y - b) <= 0.5
               for i in (-1, 0, 1) for j in (-1, 0, 1)
               for a, b in cell.get((math.floor(x) + i, math.floor(y) + j), []))


new_trees = truth["new_trees"]
growth = [abs(number(updated[i], "dbh") - number(original[i], "dbh") - truth["growth"])
          for i in live & set(updated)
          if number(updated[i], "dbh") is not None and number(original[i], "dbh") is not None]
candidates = sum(1 for r in updated.values() if r.get("status") == "candidate")
real = len(live) + len(new_trees)
print(json.dumps({
    "trees": len(original), "felled": len(felled), "new_trees": len(new_trees),
    "felled_removed": len(felled - set(updated)) / max(1, len(felled)),
    "live_removed": len(live - set(updated)) / max(1, len(live)),
    "live_removed_count": len(live - set(updated)),
    "new_confirmed": sum(near(x, y) for x, y, _ in new_trees) / max(1, len(new_trees)),
    "candidates_left": candidates,
    "candidates_per_real_tree": candidates / max(1, real),
    "dbh_growth_median_error_mm": 1000 * statistics.median(growth) if growth else None,
}))
