#pragma once
// The map's triangles, bucketed by their sorted side lengths (a dense grid over key space in
// compressed-row form), so that every map triangle whose sides each lie within a tolerance of a
// query triangle's is found by scanning a few contiguous runs of memory. 16 bytes a triangle.

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "algorithms/relocalization/triangles.h"

namespace forestmap::algorithms {

// Where a triangle sits (kd coordinates): enough to turn a key match into a sensor pose
// without touching the vertices again.
struct TriangleFrame {
  float cx = 0, cy = 0;                    // m, centroid
  float cos_heading = 1, sin_heading = 0;  // direction of the longest side, from vertex A to B
  int turn = 0;  // orientation of A, B, C: +1 counter-clockwise, -1 clockwise, 0 nearly collinear
};

TriangleFrame FrameOf(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c);

// Longest side a table key can hold (15 bits of millimetres; the top bits carry the turn).
inline constexpr double kMaxTableSide = 32.0;  // m

// cos and sin of a heading stored as a 16-bit fraction of a turn: a 1,024-entry table and a
// first-order step for the remaining 64ths of an entry (error under 2e-5).
struct HeadingTable {
  float cos_sin[1024][2];
  HeadingTable();
  void CosSin(uint16_t heading, float* c, float* s) const {
    const float* e = cos_sin[heading >> 6];
    const float delta = static_cast<float>(heading & 63) * static_cast<float>(2 * M_PI / 65536);
    *c = e[0] - delta * e[1];
    *s = e[1] + delta * e[0];
  }
};
const HeadingTable& Headings();

// 16 bytes: the centroid, the heading as a 16-bit fraction of a turn, and the sorted side
// lengths in millimetres (15 bits each; the top bits of the first two hold the orientation).
struct IndexedTriangle {
  float cx = 0, cy = 0;
  std::array<uint16_t, 3> side_key = {};
  uint16_t heading = 0;

  int side_mm(int d) const { return side_key[d] & 0x7FFF; }
  int turn() const {
    return (side_key[0] & 0x8000) == 0 ? 0 : ((side_key[1] & 0x8000) != 0 ? 1 : -1);
  }
  TriangleFrame frame() const {
    TriangleFrame f{cx, cy, 1, 0, turn()};
    Headings().CosSin(heading, &f.cos_heading, &f.sin_heading);
    return f;
  }
};
static_assert(sizeof(IndexedTriangle) == 16);

class TriangleTable {
 public:
  // `triangles` index `points` (kd coordinates); sides must not exceed `max_side` (m, at most
  // kMaxTableSide).
  TriangleTable(std::span<const Triangle> triangles, const std::vector<Eigen::Vector2d>& points,
                double max_side);
  TriangleTable(const std::vector<Triangle>& triangles, const std::vector<Eigen::Vector2d>& points,
                double max_side)
      : TriangleTable(std::span<const Triangle>(triangles), points, max_side) {}

  size_t size() const { return triangles_.size(); }
  size_t MemoryBytes() const {
    return triangles_.capacity() * sizeof(IndexedTriangle) + start_.capacity() * sizeof(uint32_t);
  }

  // Calls fn(const IndexedTriangle&) for every triangle whose three sides each lie within
  // `tolerance` (m) of `sides` (sorted, m).
  template <typename Fn>
  void ForEachMatch(const std::array<float, 3>& sides, float tolerance, Fn&& fn) const {
    const float tol_mm = tolerance * 1000.f;
    const float q[3] = {sides[0] * 1000.f, sides[1] * 1000.f, sides[2] * 1000.f};
    ForEachRun(sides, tolerance, [&](size_t first, size_t last) {
      for (size_t t = first; t < last; ++t) {
        const IndexedTriangle& tri = triangles_[t];
        if (std::abs(tri.side_mm(0) - q[0]) <= tol_mm &&
            std::abs(tri.side_mm(1) - q[1]) <= tol_mm &&
            std::abs(tri.side_mm(2) - q[2]) <= tol_mm) {
          fn(tri);
        }
      }
    });
  }

  // Number of triangles in the cells ForEachMatch scans: its cost, known in advance.
  size_t CandidateCount(const std::array<float, 3>& sides, float tolerance) const {
    size_t count = 0;
    ForEachRun(sides, tolerance, [&](size_t first, size_t last) { count += last - first; });
    return count;
  }

 private:
  // Calls fn(first, last) for each contiguous run of triangles in the key cells that overlap
  // the box of half-width `tolerance` around `sides`.
  template <typename Fn>
  void ForEachRun(const std::array<float, 3>& sides, float tolerance, Fn&& fn) const {
    int lo[3], hi[3];
    for (int d = 0; d < 3; ++d) {
      lo[d] = std::max(0, Cell(sides[d] - tolerance));
      hi[d] = std::min(cells_ - 1, Cell(sides[d] + tolerance));
      if (lo[d] > hi[d]) return;
    }
    for (int a = lo[0]; a <= hi[0]; ++a) {
      for (int b = std::max(a, lo[1]); b <= hi[1]; ++b) {
        // Sorted keys: c >= b, and the cells (a, b, c0..hi) are contiguous.
        const int c0 = std::max(b, lo[2]);
        if (c0 <= hi[2]) fn(start_[Index(a, b, c0)], start_[Index(a, b, hi[2]) + 1]);
      }
    }
  }
  int Cell(float side) const { return static_cast<int>(std::floor(side * inverse_cell_)); }
  size_t Index(int a, int b, int c) const {
    return (static_cast<size_t>(a) * cells_ + b) * cells_ + c;
  }

  int cells_ = 1;                           // key-space cells per dimension
  float inverse_cell_ = 1;                  // 1 / cell edge (m)
  std::vector<uint32_t> start_;             // cells_^3 + 1 offsets into triangles_
  std::vector<IndexedTriangle> triangles_;  // ordered by key cell
};

}  // namespace forestmap::algorithms
