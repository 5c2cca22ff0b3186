#pragma once
// Polygons with holes in a plane frame (m): a survey's boundary, a map's coverage. A ring is a
// closed sequence of vertices without the first repeated, in either orientation; a point is
// inside a polygon when it is inside its outer ring and in none of its holes (even-odd rule).

#include <Eigen/Core>
#include <vector>

namespace forestmap::algorithms {

using Ring = std::vector<Eigen::Vector2d>;

struct Polygon {
  Ring outer;
  std::vector<Ring> holes;
};

// Signed area of a ring (m^2): positive when counter-clockwise.
double SignedArea(const Ring& ring);
// Area of the polygon (m^2): its outer ring's less its holes'.
double Area(const Polygon& polygon);
// Even-odd point in ring / polygon / any of the polygons.
bool Contains(const Ring& ring, const Eigen::Vector2d& p);
bool Contains(const Polygon& polygon, const Eigen::Vector2d& p);
bool Contains(const std::vector<Polygon>& polygons, const Eigen::Vector2d& p);

// The polygons moved by `offset` (m).
std::vector<Polygon> Translated(std::vector<Polygon> polygons, const Eigen::Vector2d& offset);

// Throws std::invalid_argument naming the polygon and ring when a ring has fewer than 3
// vertices or a vertex is not finite.
void CheckPolygons(const std::vector<Polygon>& polygons);

}  // namespace forestmap::algorithms
