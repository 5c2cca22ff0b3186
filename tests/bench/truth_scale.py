#!/usr/bin/env python3
"""Is the ground truth's scale the sensor's? (Evidence for bench-mapping's similarity alignment.)

For every frame k of a sequence, the trees of frame k+STEP (within RANGE m, levelled with the
ground-truth rotations) are associated with frame k's under the true relative pose and
registered to them by 2-D least squares: the relative translation as the sensor's own geometry
measures it. Its length is compared with the ground truth's. A map built from the detections
alone has the sensor's scale, so when the two differ, a rigid alignment of that map to the ground
truth leaves an error that grows with the distance from the alignment's centre.

  tests/bench/truth_scale.py [SEQUENCE ...] [--step N] [--range M]
  (default: Wild_V01 Wild_V02 Oxford_Stein, step 10, range 20 m; reads ../shared/data)
"""
import argparse
import csv
import math
import os
import statistics

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "../../../shared/data/sequences")


def rotate(q, v):
    x, y, z, w = q
    r = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
         [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
         [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    return [sum(r[i][j] * v[j] for j in range(3)) for i in range(3)]


def read(sequence, max_range):
    folder = os.path.join(DATA, sequence)
    poses = {}
    with open(os.path.join(folder, "poses.csv")) as f:
        for row in csv.DictReader(f):
            poses[int(row["frame"])] = [float(row[k]) for k in ("x", "y", "z", "qx", "qy", "qz", "qw")]
    frames = {}  # sensor-centred, world-oriented horizontal tree positions
    with open(os.path.join(folder, "trees.csv")) as f:
        for row in csv.DictReader(f):
            frame = int(row["frame"])
            if frame not in poses:
                continue
            p = rotate(poses[frame][3:], [float(row[k]) for k in ("x", "y", "z")])
            if math.hypot(p[0], p[1]) <= max_range:
                frames.setdefault(frame, []).append((p[0], p[1]))
    return poses, frames


def register(pairs):
    """Least-squares 2-D rigid motion mapping the first points of `pairs` onto the second."""
    n = len(pairs)
    mb = [sum(p[0][k] for p in pairs) / n for k in (0, 1)]
    ma = [sum(p[1][k] for p in pairs) / n for k in (0, 1)]
    sc = ss = 0.0
    for (bx, by), (ax, ay) in pairs:
        bx, by, ax, ay = bx - mb[0], by - mb[1], ax - ma[0], ay - ma[1]
        sc += bx * ax + by * ay
        ss += bx * ay - by * ax
    th = math.atan2(ss, sc)
    c, s = math.cos(th), math.sin(th)
    return ma[0] - (c * mb[0] - s * mb[1]), ma[1] - (s * mb[0] + c * mb[1])


def measure(sequence, step, max_range, gate=0.5, min_pairs=8, min_travel=5.0):
    poses, frames = read(sequence, max_range)
    keys = sorted(frames)
    ratios = []
    for a, b in zip(keys, keys[step:]):
        tx, ty = poses[b][0] - poses[a][0], poses[b][1] - poses[a][1]
        travel = math.hypot(tx, ty)
        if travel < min_travel:
            continue
        pairs = []
        for bx, by in frames[b]:
            gx, gy = bx + tx, by + ty
            best = min(frames[a], key=lambda p: math.hypot(p[0] - gx, p[1] - gy))
            if math.hypot(best[0] - gx, best[1] - gy) < gate:
                pairs.append(((bx, by), best))
        if len(pairs) >= min_pairs:
            ex, ey = register(pairs)
            ratios.append(travel / math.hypot(ex, ey))
    return ratios


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sequences", nargs="*", default=["Wild_V01", "Wild_V02", "Oxford_Stein"])
    parser.add_argument("--step", type=int, default=10, help="frames between the two registered")
    parser.add_argument("--range", type=float, default=20.0, help="m, trees used (unbiased range)")
    args = parser.parse_args()
    for sequence in args.sequences:
        ratios = measure(sequence, args.step, args.range)
        if not ratios:
            print(f"{sequence}: no frame pair travelled 5 m with 8 common trees; try a larger --step")
            continue
        print(f"{sequence}: {len(ratios)} frame pairs {args.step} apart: ground truth / sensor "
              f"translation = 1 + {statistics.median(ratios) - 1:.5f} (median), "
              f"1 + {statistics.mean(ratios) - 1:.5f} (mean)")


if __name__ == "__main__":
    main()
