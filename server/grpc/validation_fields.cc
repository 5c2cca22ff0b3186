// Checks of single fields (validation_fields.h) and of the geometric messages (validation.h).
#include "server/grpc/validation_fields.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "server/grpc/validation.h"

namespace forestmap::server {

std::string Number(double v) {
  std::ostringstream out;
  out.precision(10);
  out << v;
  return out.str();
}

void CheckFinite(double v, const std::string& path) {
  if (std::isnan(v)) throw ValidationError(path, " is NaN; numbers must be finite");
  if (std::isinf(v)) {
    throw ValidationError(
        path, std::string(" is ") + (v > 0 ? "+inf" : "-inf") + "; numbers must be finite");
  }
}

void CheckVector(const v1::Vector3& v, const std::string& path) {
  CheckFinite(v.x(), path + ".x");
  CheckFinite(v.y(), path + ".y");
  CheckFinite(v.z(), path + ".z");
}

// What is wrong with `v` as a coordinate of a local map frame (finite, |v| < limit m): the text
// after "<field> is ", or empty.
std::string CoordinateProblem(double v, double limit) {
  if (std::isnan(v)) return "NaN; numbers must be finite";
  if (std::isinf(v)) return std::string(v > 0 ? "+inf" : "-inf") + "; numbers must be finite";
  if (std::abs(v) < limit) return "";
  return Number(v) + "; coordinates must lie within +-" + Number(limit) +
         " m (a local frame; keep georeferenced offsets in the map's crs)";
}

void CheckCoordinate(double v, double limit, const std::string& path) {
  const std::string problem = CoordinateProblem(v, limit);
  if (!problem.empty()) throw ValidationError(path, " is " + problem);
}

// A DBH: finite, >= 0 and at most kMaxDbh.
void CheckDbh(double dbh, const std::string& path) {
  CheckFinite(dbh, path);
  if (dbh < 0 || dbh > kMaxDbh) {
    throw ValidationError(path,
                          " is " + Number(dbh) + "; it must be in [0, " + Number(kMaxDbh) + "] m");
  }
}

// A position: x and y within kMaxHorizontalCoordinate, z within kMaxVerticalCoordinate.
void CheckPosition(const v1::Vector3& v, const std::string& path) {
  CheckCoordinate(v.x(), kMaxHorizontalCoordinate, path + ".x");
  CheckCoordinate(v.y(), kMaxHorizontalCoordinate, path + ".y");
  CheckCoordinate(v.z(), kMaxVerticalCoordinate, path + ".z");
}

// A direction: finite and not zero. Its length does not matter: it is normalised, scaled by its
// largest component first (server/grpc/convert.cc), so 1e308 and 1e-300 give their direction.
void CheckDirection(const v1::Vector3& v, const std::string& path) {
  CheckVector(v, path);
  if (std::max({std::abs(v.x()), std::abs(v.y()), std::abs(v.z())}) == 0) {
    throw ValidationError(path, " is a zero vector; it must give a direction");
  }
}

void ValidatePose(const v1::Pose& pose, const std::string& path) {
  if (pose.has_translation()) CheckPosition(pose.translation(), path + ".translation");
  if (!pose.has_rotation()) return;  // identity
  const v1::Quaternion& q = pose.rotation();
  const std::string rotation = path + ".rotation";
  CheckFinite(q.x(), rotation + ".x");
  CheckFinite(q.y(), rotation + ".y");
  CheckFinite(q.z(), rotation + ".z");
  CheckFinite(q.w(), rotation + ".w");
  const double norm = std::sqrt(q.x() * q.x() + q.y() * q.y() + q.z() * q.z() + q.w() * q.w());
  if (std::abs(norm - 1.0) > kUnitQuaternionTolerance) {
    throw ValidationError(rotation,
                          " is not a unit quaternion (norm " + Number(norm) + "); normalise it");
  }
}

void ValidateBox(const v1::Box2& box, const std::string& path) {
  CheckFinite(box.min_x(), path + ".min_x");
  CheckFinite(box.min_y(), path + ".min_y");
  CheckFinite(box.max_x(), path + ".max_x");
  CheckFinite(box.max_y(), path + ".max_y");
  if (box.min_x() > box.max_x() || box.min_y() > box.max_y()) {
    throw ValidationError(path, " is empty: min_x <= max_x and min_y <= max_y are required");
  }
}

void ValidateBoundary(const v1::SurveyBoundary& boundary, const std::string& path) {
  int64_t vertices = 0;
  for (int p = 0; p < boundary.polygons_size(); ++p) {
    const v1::Polygon& polygon = boundary.polygons(p);
    for (int r = -1; r < polygon.holes_size(); ++r) {
      const v1::Ring& ring = r < 0 ? polygon.outer() : polygon.holes(r);
      const std::string of = Indexed(path + ".polygons", p);
      const std::string at = r < 0 ? of + ".outer" : Indexed(of + ".holes", r);
      if (ring.vertices_size() < 3) {
        throw ValidationError(at, " has " + std::to_string(ring.vertices_size()) +
                                      " vertices; a ring needs at least 3");
      }
      vertices += ring.vertices_size();
      if (vertices > kMaxBoundaryVertices) {
        throw ValidationError(path, " has over 100000 vertices; simplify it");
      }
      for (int i = 0; i < ring.vertices_size(); ++i) {
        const std::string vertex = Indexed(at + ".vertices", i);
        CheckCoordinate(ring.vertices(i).x(), kMaxHorizontalCoordinate, vertex + ".x");
        CheckCoordinate(ring.vertices(i).y(), kMaxHorizontalCoordinate, vertex + ".y");
      }
    }
  }
}

}  // namespace forestmap::server
