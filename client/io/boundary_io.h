#pragma once
// A map's survey boundary as files hold it: read from a GIS polygon layer (GeoPackage, GeoJSON,
// shapefile or any vector format GDAL opens: Polygon and MultiPolygon features, with holes) or
// from a CSV ring (columns x and y, one row per vertex, one ring, no holes), and written as a
// polygon layer beside the trees of an export.
//
// Checks (errors are CsvError naming the file and, where there is one, the feature, polygon and
// ring): every ring closed in a GIS file (its last vertex equal to its first), at least 3
// distinct vertices, finite coordinates, a non-zero area, no ring crossing itself or another ring
// of its polygon (GDAL's validity check), and at most kMaxBoundaryVertices vertices in all. A
// vertex repeated right after itself is dropped; a CSV ring may repeat its first vertex at its end
// or not.

#include <cstddef>
#include <string>
#include <vector>

#include "algorithms/core/polygon.h"
#include "client/io/geo_io.h"

namespace forestmap::client {

// Vertices a boundary may have, all rings together (the server's limit).
inline constexpr size_t kMaxBoundaryVertices = 100000;

struct BoundaryFile {
  std::vector<algorithms::Polygon> polygons;  // rings without the first vertex repeated
  std::string crs_wkt;  // the layer's CRS as WKT; empty when it has none (always for CSV)
};

// By extension as tree files are (TreeFormatOfPath): .gpkg, .geojson/.json, .shp through GDAL,
// anything else a CSV ring. `layer`: the GIS layer to read; empty: the only one, else the only
// one with polygons.
BoundaryFile ReadBoundaryFile(const std::string& path, const std::string& layer = "");

// The checks above on polygons from anywhere; `path` names them in messages.
void CheckBoundaryPolygons(const std::vector<algorithms::Polygon>& polygons,
                           const std::string& path);

// Writes `polygons` (map frame, CRS `crs` as the trees of WriteGeoTrees) as layer `layer` of
// `path` in `format` (GeoPackage: beside the other layers of an existing file, replacing a layer
// of that name; GeoJSON, shapefile: the file), one Polygon feature per polygon with a field
// `polygon` (its index, from 0).
void WriteGeoBoundary(const std::string& path, TreeFormat format,
                      const std::vector<algorithms::Polygon>& polygons, const std::string& crs,
                      const std::string& layer = "boundary");

}  // namespace forestmap::client
