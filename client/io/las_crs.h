#pragma once
// The coordinate reference system a LAS file declares (ASPRS LAS 1.4 R15, section 2.5): the
// OGC WKT VLR (LASF_Projection 2112) or the GeoTIFF GeoKeyDirectory VLR (LASF_Projection 34735,
// ProjectedCSTypeGeoKey 3072 or GeographicTypeGeoKey 2048 as an EPSG code).

#include <string>

namespace forestmap::client {

// WKT when the file has a WKT VLR, else "EPSG:n" from its GeoKeys, else "" (no CRS, or not a
// .las file). Throws ScanError "FILE: byte N: ..." for VLRs that run past the point data.
std::string ReadLasCrs(const std::string& path);

// Parses a LAS file's bytes as above; `path` names it in errors.
std::string LasCrsFromBytes(const std::string& bytes, const std::string& path);

}  // namespace forestmap::client
