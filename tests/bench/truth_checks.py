#!/usr/bin/env python3
"""Two properties of the real sequences that decide how a map built from them can be scored.

1. Is the ground truth's scale the sensor's? (Why bench-mapping aligns by similarity.)

For every frame k of a sequence, the trees of frame k+STEP (within RANGE m, levelled with the
ground-truth rotations) are associated with frame k's under the true relative pose and
registered to them by 2-D least squares: the relative translation as the sensor's own geometry
measures it. Its length is compared with the ground truth's. A map built from the detections
alone has the sensor's scale, so when the two differ, a rigid alignment of that map to the ground
truth leaves an error that grows with the distance from the alignment's centre.

2. Do the detected stems' heights follow the sensor's? Between consecutive frames, the median
height change of their common stems (levelled with the ground-truth rotations) is chained and
compared with the ground truth's height change over the whole sequence. If the stems' heights
were fixed points of the trees (their bases), the two would agree.

  tests/bench/truth_checks.py [SEQUENCE ...] [--step N] [--range M]
  (default: Wild_V01 Wild_V02 Oxford_Stein, step 10, range 20 m; reads $FORESTMAP_SHARED_DATA,
  default ../shared/data)
"""
import argparse
import csv
import math
import os
import statistics

DATA = os.path.join(os.environ.get("FORESTMAP_SHARED_DATA") or os.path.normpath(
    os.path.join(os.path.dirname(os.path.abspath(__file__)), "../../../shared/data")), "sequences")


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
                frames.setdefault(frame, []).append((p[0], p[1], p[2]))
    return poses, frames


def register(pairs):
    """Least-squares 2-D rigid motion mapping the first points of `pairs` onto the second."""
    n = len(pairs)
    mb = [sum(p[0][k] for p in pairs) / n for k in (0, 1)]
    ma = [sum(p[1][k] for p in pairs) / n for k in (0, 1)]
    sc = ss = 0.0
    for (bx, by, _), (ax, ay, _) in pairs:
        bx, by, ax, ay = bx - mb[0], by - mb[1], ax - ma[0], ay - ma[1]
        sc += bx * ax + by * ay
        ss += bx * ay - by * ax
    th = math.atan2(ss, sc)
    c, s = math.cos(th), math.sin(th)
    return ma[0] - (c * mb[0] - s * mb[1]), ma[1] - (s * mb[0] + c * mb[1])


def common_trees(frames, poses, a, b, gate=0.5):
    """(tree in b, its match in a) under the true relative pose, sensor-centred."""
    tx, ty = poses[b][0] - poses[a][0], poses[b][1] - poses[a][1]
    pairs = []
    for tree in frames[b]:
        gx, gy = tree[0] + tx, tree[1] + ty
        best = min(frames[a], key=lambda p: math.hypot(p[0] - gx, p[1] - gy))
        if math.hypot(best[0] - gx, best[1] - gy) < gate:
            pairs.append((tree, best))
    return pairs


def measure_heights(poses, frames):
    """Per consecutive frames: (height change the stems show, true height change)."""
    keys = sorted(frames)
    steps = []
    for a, b in zip(keys, keys[1:]):
        pairs = common_trees(frames, poses, a, b)
        if pairs:
            stems = statistics.median(pa[2] - pb[2] for pb, pa in pairs)
            steps.append((stems, poses[b][2] - poses[a][2]))
    return steps


def measure_scale(poses, frames, step, min_pairs=8, min_travel=5.0):
    keys = sorted(frames)
    ratios = []
    for a, b in zip(keys, keys[step:]):
        tx, ty = poses[b][0] - poses[a][0], poses[b][1] - poses[a][1]
        travel = math.hypot(tx, ty)
        if travel < min_travel:
            continue
        pairs = common_trees(frames, poses, a, b)
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
        if not os.path.isfile(os.path.join(DATA, sequence, "poses.csv")):
            parser.error(f"no sequence '{sequence}' (poses.csv, trees.csv) under {DATA}")
        poses, frames = read(sequence, args.range)
        ratios = measure_scale(poses, frames, args.step)
        if ratios:
            print(f"{sequence}: {len(ratios)} frame pairs {args.step} apart: ground truth / sensor "
                  f"translation = 1 + {statistics.median(ratios) - 1:.5f} (median), "
                  f"1 + {statistics.mean(ratios) - 1:.5f} (mean)")
        else:
            print(f"{sequence}: no frame pair travelled 5 m with 8 common trees; try a larger --step")
        steps = measure_heights(poses, frames)
        slope = sum(s * t for s, t in steps) / sum(t * t for _, t in steps)
        gap = max(abs(sum(s for s, _ in steps[:k]) - sum(t for _, t in steps[:k]))
                  for k in range(len(steps) + 1))
        print(f"{sequence}: heights: between consecutive frames the stems show {slope:.2f} of the "
              f"sensor's height change; chained, they drift up to {gap:.1f} m from the truth")


if __name__ == "__main__":
    main()
