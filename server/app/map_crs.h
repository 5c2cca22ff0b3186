#pragma once
// A map's coordinate reference system in the server (geo/crs.h): validated and stored in
// canonical form, and applied to relocalization answers (the sensor's pose in WGS84).

#include <memory>
#include <optional>
#include <string>

#include "algorithms/core/geometry.h"
#include "geo/crs.h"

namespace forestmap::server {

// The CRS to store for a new map's `crs`: "" for none, "EPSG:n" when it has an EPSG code, else
// its WKT. Throws ValidationError "crs \"...\": PROJ's reason; give ..." for one PROJ rejects or
// whose x and y are not metres.
std::string CanonicalCrs(const std::string& crs);

// The transform of a stored map's answers to WGS84; null for no CRS, and for a CRS stored before
// maps had to be in metres or in free text before validation (their answers stay in map
// coordinates).
std::shared_ptr<const geo::MapToWgs84> AnswersToWgs84(const std::string& crs);

// The WGS84 pose of the sensor at `map_from_sensor` (heading: of the sensor's x axis); nullopt
// for a point PROJ cannot transform (far outside the CRS's area).
std::optional<geo::GeodeticPose> GeodeticPoseOf(const Eigen::Isometry3d& map_from_sensor,
                                                const geo::MapToWgs84& to_wgs84);

}  // namespace forestmap::server
