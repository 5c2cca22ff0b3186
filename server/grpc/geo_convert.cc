#include "server/grpc/geo_convert.h"

#include "proto/geometry_convert.h"
#include "server/app/map_crs.h"

namespace forestmap::server {

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

std::optional<geo::GeodeticPose> AddGeodetic(v1::RelocalizeResponse& response,
                                             const geo::MapToWgs84& to_wgs84) {
  if (response.status() != v1::RelocalizeResponse::STATUS_LOCALIZED) return std::nullopt;
  // The pose as the answer carries it (a unit quaternion), so the heading is the client's.
  const std::optional<geo::GeodeticPose> g =
      GeodeticPoseOf(FromProto(response.map_from_sensor()), to_wgs84);
  if (!g) return std::nullopt;
  v1::GeodeticPose& out = *response.mutable_geodetic();
  out.set_latitude_deg(g->latitude_deg);
  out.set_longitude_deg(g->longitude_deg);
  out.set_ellipsoidal_height_m(g->ellipsoidal_height_m);
  out.set_true_heading_deg(g->true_heading_deg);
  out.set_grid_convergence_deg(g->grid_convergence_deg);
  out.set_transformation_accuracy_m(g->transformation.accuracy_m);
  out.set_ballpark_transformation(g->transformation.ballpark);
  return g;
}

}  // namespace forestmap::server
