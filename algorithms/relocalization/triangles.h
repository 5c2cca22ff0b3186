#pragma once
// Rotation-invariant constellation keys: triangles of nearby trees, keyed by their sorted side
// lengths. A triangle of three detected true trees exists in the map whatever else was missed or
// falsely detected, so its key is robust to misses and false stems (unlike a fixed k-NN list).

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <vector>

namespace forestmap::algorithms {

// Vertices ordered canonically: a = |BC| <= b = |CA| <= c = |AB| (A is opposite the shortest
// side). Indices refer to the caller's point list.
struct Triangle {
  std::array<float, 3> sides;      // m, a <= b <= c
  std::array<uint32_t, 3> vertex;  // A, B, C
};

struct TriangleOptions {
  double max_side = 5.0;  // m, longest side of a triangle
  double min_side = 0.5;  // m, shortest side (closer stems are unstable and often one tree)
  void Check() const;
};

// Canonical triangle of points i, j, k of `points`.
Triangle MakeTriangle(const std::vector<Eigen::Vector2d>& points, uint32_t i, uint32_t j,
                      uint32_t k);

// Every triangle whose sides are all within [min_side, max_side], each reported once, from its
// smallest vertex index; only anchors in [begin, end) (to split the work across threads).
// `neighbours[i]` must list the indices of points within max_side of point i.
std::vector<Triangle> EnumerateTriangles(const std::vector<Eigen::Vector2d>& points,
                                         const std::vector<std::vector<uint32_t>>& neighbours,
                                         const TriangleOptions& options, size_t begin = 0,
                                         size_t end = SIZE_MAX);

}  // namespace forestmap::algorithms
