#pragma once
// A map's CRS on the server (geo/crs.h): validated and stored in canonical form, described in
// map messages (WKT, EPSG), and applied to relocalization answers (WGS84 pose).

#include <string>

#include "forestmap/v1/maps.pb.h"
#include "forestmap/v1/relocalization.pb.h"
#include "geo/crs.h"

namespace forestmap::server {

// The CRS to store for a CreateMap `crs`: "" for none, "EPSG:n" when it has an EPSG code, else
// its WKT. Throws ValidationError "crs \"...\": PROJ's reason; give ..." for one PROJ rejects.
std::string CanonicalCrs(const std::string& crs);

// Sets map.crs_wkt and map.crs_epsg from map.crs (left empty for a CRS stored before CRSs were
// validated that PROJ does not know).
void DescribeCrs(v1::Map& map);

// Adds the WGS84 pose of a LOCALIZED answer (nothing for other answers). A point PROJ cannot
// transform (far outside the CRS's area) leaves the answer without it.
void AddGeodetic(v1::RelocalizeResponse& response, const geo::MapToWgs84& to_wgs84);

}  // namespace forestmap::server
