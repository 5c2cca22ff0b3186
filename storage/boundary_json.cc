#include "storage/boundary_json.h"

#include <cmath>
#include <nlohmann/json.hpp>
#include <stdexcept>

namespace forestmap::storage::internal {

using Code = StorageError::Code;

namespace {

nlohmann::json RingJson(const BoundaryRing& ring) {
  nlohmann::json points = nlohmann::json::array();
  for (const BoundaryPoint& p : ring) points.push_back({p.x, p.y});
  return points;
}

BoundaryRing RingOf(const nlohmann::json& points) {
  BoundaryRing ring;
  if (!points.is_array()) throw std::invalid_argument("a ring is not an array");
  ring.reserve(points.size());
  for (const nlohmann::json& point : points) {
    if (!point.is_array() || point.size() != 2 || !point[0].is_number() || !point[1].is_number()) {
      throw std::invalid_argument("a vertex is not [x, y]");
    }
    ring.push_back({point[0].get<double>(), point[1].get<double>()});
  }
  return ring;
}

std::string RingName(size_t polygon, size_t ring) {
  return "boundary polygon " + std::to_string(polygon) +
         (ring == 0 ? " outer ring" : " hole " + std::to_string(ring - 1));
}

}  // namespace

void CheckBoundary(const std::string& map_name, const Boundary& boundary) {
  size_t vertices = 0;
  for (size_t p = 0; p < boundary.size(); ++p) {
    for (size_t r = 0; r <= boundary[p].holes.size(); ++r) {
      const BoundaryRing& ring = r == 0 ? boundary[p].outer : boundary[p].holes[r - 1];
      if (ring.size() < 3) {
        throw StorageError(Code::kInvalidArgument, "map '" + map_name + "': " + RingName(p, r) +
                                                       " has " + std::to_string(ring.size()) +
                                                       " vertices; a ring needs at least 3");
      }
      for (const BoundaryPoint& point : ring) {
        if (!std::isfinite(point.x) || !std::isfinite(point.y)) {
          throw StorageError(Code::kInvalidArgument, "map '" + map_name + "': " + RingName(p, r) +
                                                         " has a vertex that is not finite");
        }
      }
      vertices += ring.size();
    }
  }
  if (vertices > kMaxBoundaryVertices) {
    throw StorageError(Code::kInvalidArgument,
                       "map '" + map_name + "': the boundary has " + std::to_string(vertices) +
                           " vertices; at most " + std::to_string(kMaxBoundaryVertices));
  }
}

std::string EncodeBoundary(const Boundary& boundary) {
  if (boundary.empty()) return {};
  nlohmann::json polygons = nlohmann::json::array();
  for (const BoundaryPolygon& polygon : boundary) {
    nlohmann::json rings = nlohmann::json::array();
    rings.push_back(RingJson(polygon.outer));
    for (const BoundaryRing& hole : polygon.holes) rings.push_back(RingJson(hole));
    polygons.push_back(std::move(rings));
  }
  return polygons.dump();  // numbers written so that they parse back to the same doubles
}

Boundary DecodeBoundary(const std::string& map_name, const std::string& text) {
  if (text.empty()) return {};
  try {
    const nlohmann::json polygons = nlohmann::json::parse(text);
    if (!polygons.is_array()) throw std::invalid_argument("not an array of polygons");
    Boundary boundary;
    for (const nlohmann::json& rings : polygons) {
      if (!rings.is_array() || rings.empty()) throw std::invalid_argument("a polygon has no ring");
      BoundaryPolygon polygon;
      polygon.outer = RingOf(rings[0]);
      for (size_t r = 1; r < rings.size(); ++r) polygon.holes.push_back(RingOf(rings[r]));
      boundary.push_back(std::move(polygon));
    }
    return boundary;
  } catch (const std::exception& e) {
    throw StorageError(Code::kInternal,
                       "map '" + map_name + "': the stored boundary is damaged: " + e.what());
  }
}

}  // namespace forestmap::storage::internal
