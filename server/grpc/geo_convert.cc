#include "server/grpc/geo_convert.h"

#include <cmath>

#include "proto/geometry_convert.h"
#include "server/grpc/validation.h"

namespace forestmap::server {

std::string CanonicalCrs(const std::string& crs) {
  if (crs.empty()) return crs;
  constexpr size_t kMaxShown = 64;
  const std::string shown = crs.size() > kMaxShown ? crs.substr(0, kMaxShown) + "..." : crs;
  geo::CrsInfo info;
  try {
    info = geo::ParseCrs(crs);
  } catch (const geo::CrsError& error) {
    throw ValidationError("crs \"" + shown +
                          "\" is not a coordinate reference system PROJ knows (" + error.what() +
                          "); give an EPSG code (EPSG:2959), WKT or a PROJ string");
  }
  if (!info.map_problem.empty()) {
    throw ValidationError("crs \"" + shown + "\" (" + info.name +
                          ") cannot be a map's: " + info.map_problem +
                          ", and a map's x and y are metres; reproject the trees to a projected "
                          "CRS in metres (forestmap map create --to-crs utm)");
  }
  return info.Canonical();
}

void DescribeCrs(v1::Map& map) {
  if (map.crs().empty()) return;
  try {
    const geo::CrsInfo info = geo::ParseCrs(map.crs());
    map.set_crs_wkt(info.wkt);
    map.set_crs_epsg(info.epsg);
  } catch (const geo::CrsError&) {
    // A free-text CRS from before validation: described by its text alone.
  }
}

void AddGeodetic(v1::RelocalizeResponse& response, const geo::MapToWgs84& to_wgs84) {
  if (response.status() != v1::RelocalizeResponse::LOCALIZED) return;
  const Eigen::Isometry3d map_from_sensor = FromProto(response.map_from_sensor());
  const Eigen::Vector3d forward = map_from_sensor.linear() * Eigen::Vector3d::UnitX();
  const Eigen::Vector3d at = map_from_sensor.translation();
  try {
    const geo::GeodeticPose g =
        to_wgs84.Convert(at.x(), at.y(), at.z(), std::atan2(forward.y(), forward.x()));
    v1::GeodeticPose& out = *response.mutable_geodetic();
    out.set_latitude_deg(g.latitude_deg);
    out.set_longitude_deg(g.longitude_deg);
    out.set_ellipsoidal_height_m(g.ellipsoidal_height_m);
    out.set_true_heading_deg(g.true_heading_deg);
    out.set_grid_convergence_deg(g.grid_convergence_deg);
    out.set_transformation_accuracy_m(g.transformation.accuracy_m);
    out.set_ballpark_transformation(g.transformation.ballpark);
  } catch (const geo::CrsError&) {
    // Outside the CRS's area: the projected pose stands alone.
  }
}

}  // namespace forestmap::server
