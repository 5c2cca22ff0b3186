#!/usr/bin/env python3
"""One question over many plot maps, through forestmapd: the Wild_V01 map cut into 1 ha plot maps
(100 m tiles holding 30 trees or more), every STEP-th Wild_V02 frame relocalized (a) over every
plot map with a prior (the truth moved by N(0, 10 m) per axis, radius 30 m) and (b) without a
prior over the 16 largest plots (the server's limit a question). Prints frames, right (within
1 m of the truth), wrong, not localized, and the server's time per question (p50 / p95).

  tests/bench/plot_maps.py [STEP]     (after ./deploy/build.sh; FORESTMAP_SHARED_DATA: ../shared/data)
"""
import csv
import math
import os
import random
import subprocess
import sys
import tempfile
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "build", "python"))
import numpy as np  # noqa: E402

import forestmap  # noqa: E402

DATA = os.environ.get("FORESTMAP_SHARED_DATA", os.path.join(ROOT, "..", "shared", "data"))
SEQ = os.path.join(DATA, "sequences")
STEP = int(sys.argv[1]) if len(sys.argv) > 1 else 10
TILE, MIN_TREES, COLUMNS = 100.0, 30, ("x", "y", "z", "dbh")
OFFSET = (0.051, 0.102)  # map_V01_from_map_V02 (the data's README); its 0.014 deg yaw ignored


def plot_name(x, y):
    return "plot_%d_%d" % (math.floor(x / TILE) + 100, math.floor(y / TILE) + 100)


def read_csv(path):
    with open(path) as f:
        return list(csv.DictReader(f))


def main():
    trees = np.array([[float(r[c]) for c in COLUMNS]
                      for r in read_csv(os.path.join(SEQ, "Wild_V01", "map.csv"))])
    poses = {int(r["frame"]): r for r in read_csv(os.path.join(SEQ, "Wild_V02", "poses.csv"))}
    frames = {}
    for r in read_csv(os.path.join(SEQ, "Wild_V02", "trees.csv")):
        frames.setdefault(int(r["frame"]), []).append([float(r[c]) for c in COLUMNS])
    with tempfile.TemporaryDirectory() as scratch:
        address = "127.0.0.1:50098"
        server = subprocess.Popen([os.path.join(ROOT, "build", "server", "forestmapd"), "--db",
                                   os.path.join(scratch, "plots.db"), "--listen", address],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            client = forestmapd_client(address)
            names = {}
            for name in sorted({plot_name(x, y) for x, y in trees[:, :2]}):
                mine = np.array([plot_name(x, y) == name for x, y in trees[:, :2]])
                if mine.sum() >= MIN_TREES:
                    client.create_map(name, trees[mine], columns=COLUMNS)
                    names[name] = int(mine.sum())
            largest = sorted(names, key=lambda n: -names[n])[:16]
            print(f"{len(names)} plot maps of 1 ha (Wild_V01, {len(trees)} trees); "
                  f"every {STEP}th Wild_V02 frame")
            rng = random.Random(1)
            cases = {"every plot map, prior 30 m (truth + N(0, 10 m))": [],
                     "the 16 largest plot maps, no prior": []}
            for f in sorted(frames)[::STEP]:
                x = float(poses[f]["x"]) + OFFSET[0]
                y = float(poses[f]["y"]) + OFFSET[1]
                query = np.array(frames[f])
                prior = (x + rng.gauss(0, 10), y + rng.gauss(0, 10), 30.0)
                a = client.relocalize(None, query, prior=prior, maps_matching="plot_*",
                                      columns=COLUMNS)
                b = client.relocalize(None, query, maps=largest, columns=COLUMNS)
                for answers, answer in zip(cases.values(), (a, b)):
                    error = math.hypot(answer.x - x, answer.y - y) if answer.localized else 0.0
                    answers.append((answer, error))
            for case, answers in cases.items():
                right = sum(1 for a, e in answers if a.localized and e <= 1.0)
                wrong = sum(1 for a, e in answers if a.localized and e > 1.0)
                ms = sorted(a.server_ms for a, _ in answers)
                print(f"| {case} | {len(answers)} | {right} | {wrong} | {len(answers) - right - wrong}"
                      f" | {ms[len(ms) // 2]:.1f} / {ms[int(0.95 * len(ms))]:.1f} ms |")
        finally:
            server.terminate()
            server.wait()


def forestmapd_client(address):
    client = forestmap.Client(address)
    for _ in range(100):
        try:
            client.list_maps()
            return client
        except forestmap.ForestMapError:
            time.sleep(0.1)
    raise SystemExit("plot_maps: forestmapd did not start on " + address)


if __name__ == "__main__":
    main()
