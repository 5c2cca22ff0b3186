#pragma once
// Delaunay triangulation of points in the plane: incremental Bowyer-Watson (Bowyer 1981, Watson
// 1981) in a space-filling-curve order, with exact predicates. Coordinates are rounded to a
// quantum (1 mm, coarser for extents beyond 67 km) and the orientation and in-circle
// determinants evaluated exactly in 64- and 128-bit integers, so collinear and cocircular points
// (a planted grid) never make the triangulation inconsistent.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <vector>

namespace forestmap::algorithms {

struct Triangulation {
  // Counter-clockwise vertex indices into the input points; points that round to the same
  // position as an earlier one take no part (they are no vertex).
  std::vector<std::array<uint32_t, 3>> triangles;
  // neighbours[t][i]: the triangle across the edge opposite triangles[t][i] (from vertex i + 1 to
  // vertex i + 2), or -1 on the convex hull.
  std::vector<std::array<int32_t, 3>> neighbours;
};

// Throws std::invalid_argument for a point that is not finite.
Triangulation Delaunay(const std::vector<Eigen::Vector2d>& points);

// Radius of the circle through three points (m; infinite when they are collinear).
double Circumradius(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c);

}  // namespace forestmap::algorithms
