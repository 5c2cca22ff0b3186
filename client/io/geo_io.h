#pragma once
// Map trees as GIS files through GDAL/OGR (the one file that includes GDAL): GeoPackage,
// GeoJSON and ESRI shapefiles, with the map's CRS and every attribute, so that QGIS, R (sf,
// lidR) and ArcGIS open them as they are.
//
// Written layout: one point layer "trees"; point = (x, y) in the map CRS; fields id (integer),
// x, y, z, dbh (real, metres; null when unknown), then one string field per attribute name of
// any row, null attributes included (in name order, named as ExportedAttributes in
// tree_columns.h says; null where a row has no value). Reading
// takes the point's x and y (and z when the geometry has one) and the fields by name as
// tree_columns.h resolves them (--columns and --dbh-unit apply to field names); a null or unset
// field is a null attribute.
//
// Errors are CsvError (the tree-file error type) naming the file and, where there is one, the
// feature and field: "FILE: feature 3: field 'dbh': ...". A failed write removes what it made.

#include <string>
#include <vector>

#include "client/io/tree_columns.h"
#include "client/io/tree_csv.h"

namespace forestmap::client {

enum class TreeFormat { kCsv, kGeoJson, kGeoPackage, kShapefile };

// "csv", "geojson", "gpkg", "shp": throws std::invalid_argument otherwise.
TreeFormat ParseTreeFormat(const std::string& name);
// By extension: .geojson/.json, .gpkg, .shp; anything else is CSV.
TreeFormat TreeFormatOfPath(const std::string& path);
const char* TreeFormatName(TreeFormat format);

// Writes `rows` in `format` (not kCsv) to `path`, replacing an existing file. `crs` is the
// map's CRS as stored (EPSG:n, WKT or PROJ string); empty: none.
void WriteGeoTrees(const std::string& path, TreeFormat format, const std::vector<MapTreeRow>& rows,
                   const std::string& crs);

struct GeoTrees {
  std::vector<MapTreeRow> rows;
  std::string crs_wkt;  // the layer's CRS as WKT; empty when it has none
};

// Reads the first layer of a GIS file (any vector format GDAL opens).
GeoTrees ReadGeoTrees(const std::string& path, const TreeFileOptions& options);

}  // namespace forestmap::client
