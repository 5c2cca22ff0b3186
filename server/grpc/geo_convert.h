#pragma once
// A map's CRS in the gRPC messages (server/app/map_crs.h stores and applies it): described in map
// messages (WKT, EPSG), and the WGS84 pose added to relocalization answers.

#include <optional>

#include "forestmap/v1/maps.pb.h"
#include "forestmap/v1/relocalization.pb.h"
#include "geo/crs.h"

namespace forestmap::server {

// Sets map.crs_wkt and map.crs_epsg from map.crs (left empty for a CRS stored before CRSs were
// validated that PROJ does not know).
void DescribeCrs(v1::Map& map);

// Adds the WGS84 pose of a LOCALIZED answer (nothing for other answers) and returns it. A point
// PROJ cannot transform (far outside the CRS's area) leaves the answer without it (nullopt).
std::optional<geo::GeodeticPose> AddGeodetic(v1::RelocalizeResponse& response,
                                             const geo::MapToWgs84& to_wgs84);

}  // namespace forestmap::server
