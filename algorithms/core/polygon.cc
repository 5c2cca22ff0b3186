#include "algorithms/core/polygon.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace forestmap::algorithms {

double SignedArea(const Ring& ring) {
  double twice = 0;
  for (size_t i = 0, j = ring.size() - 1; i < ring.size(); j = i++) {
    twice += ring[j].x() * ring[i].y() - ring[i].x() * ring[j].y();
  }
  return ring.empty() ? 0.0 : 0.5 * twice;
}

double Area(const Polygon& polygon) {
  double area = std::abs(SignedArea(polygon.outer));
  for (const Ring& hole : polygon.holes) area -= std::abs(SignedArea(hole));
  return area;
}

bool Contains(const Ring& ring, const Eigen::Vector2d& p) {
  bool inside = false;
  for (size_t i = 0, j = ring.size() - 1; i < ring.size(); j = i++) {
    const Eigen::Vector2d &a = ring[i], &b = ring[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) &&
        p.x() < a.x() + (p.y() - a.y()) * (b.x() - a.x()) / (b.y() - a.y())) {
      inside = !inside;
    }
  }
  return inside;
}

bool Contains(const Polygon& polygon, const Eigen::Vector2d& p) {
  if (!Contains(polygon.outer, p)) return false;
  for (const Ring& hole : polygon.holes) {
    if (Contains(hole, p)) return false;
  }
  return true;
}

bool Contains(const std::vector<Polygon>& polygons, const Eigen::Vector2d& p) {
  for (const Polygon& polygon : polygons) {
    if (Contains(polygon, p)) return true;
  }
  return false;
}

std::vector<Polygon> Translated(std::vector<Polygon> polygons, const Eigen::Vector2d& offset) {
  for (Polygon& polygon : polygons) {
    for (Eigen::Vector2d& v : polygon.outer) v += offset;
    for (Ring& hole : polygon.holes) {
      for (Eigen::Vector2d& v : hole) v += offset;
    }
  }
  return polygons;
}

void CheckPolygons(const std::vector<Polygon>& polygons) {
  auto check = [](const Ring& ring, size_t polygon, const std::string& which) {
    const std::string where = "polygon " + std::to_string(polygon) + " " + which;
    if (ring.size() < 3) throw std::invalid_argument(where + " has fewer than 3 vertices");
    for (const Eigen::Vector2d& v : ring) {
      if (!v.allFinite()) throw std::invalid_argument(where + " has a vertex that is not finite");
    }
  };
  for (size_t i = 0; i < polygons.size(); ++i) {
    check(polygons[i].outer, i, "outer ring");
    for (size_t h = 0; h < polygons[i].holes.size(); ++h) {
      check(polygons[i].holes[h], i, "hole " + std::to_string(h));
    }
  }
}

}  // namespace forestmap::algorithms
