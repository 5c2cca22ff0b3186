#include "server/app/map_crs.h"

#include <cmath>

#include "server/app/errors.h"

namespace forestmap::server {

std::string CanonicalCrs(const std::string& crs) {
  if (crs.empty()) return crs;
  constexpr size_t kMaxShown = 64;
  const std::string shown = crs.size() > kMaxShown ? crs.substr(0, kMaxShown) + "..." : crs;
  geo::CrsInfo info;
  try {
    info = geo::ParseCrs(crs);
  } catch (const geo::CrsError& error) {
    throw ValidationError(
        "crs", " \"" + shown + "\" is not a coordinate reference system PROJ knows (" +
                   error.what() + "); give an EPSG code (EPSG:2959), WKT or a PROJ string");
  }
  if (!info.map_problem.empty()) {
    throw ValidationError(
        "crs", " \"" + shown + "\" (" + info.name + ") cannot be a map's: " + info.map_problem +
                   ", and a map's x and y are metres; reproject the trees to a projected "
                   "CRS in metres (forestmap map create --to-crs utm)");
  }
  return info.Canonical();
}

std::shared_ptr<const geo::MapToWgs84> AnswersToWgs84(const std::string& crs) {
  if (crs.empty()) return nullptr;
  try {
    if (!geo::ParseCrs(crs).map_problem.empty()) return nullptr;
    return std::make_shared<const geo::MapToWgs84>(crs);
  } catch (const geo::CrsError&) {
    return nullptr;
  }
}

std::optional<geo::GeodeticPose> GeodeticPoseOf(const Eigen::Isometry3d& map_from_sensor,
                                                const geo::MapToWgs84& to_wgs84) {
  const Eigen::Vector3d forward = map_from_sensor.linear() * Eigen::Vector3d::UnitX();
  const Eigen::Vector3d at = map_from_sensor.translation();
  try {
    return to_wgs84.Convert(at.x(), at.y(), at.z(), std::atan2(forward.y(), forward.x()));
  } catch (const geo::CrsError&) {
    return std::nullopt;  // outside the CRS's area: the projected pose stands alone
  }
}

}  // namespace forestmap::server
