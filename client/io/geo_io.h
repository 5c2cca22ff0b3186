#pragma once
// Map trees as GIS files through GDAL/OGR (the one file that includes GDAL): GeoPackage,
// GeoJSON and ESRI shapefiles, with the map's CRS and every attribute, so that QGIS, R (sf,
// lidR) and ArcGIS open them as they are.
//
// Written layout: one point layer (named after the map; a shapefile's is its file name); point =
// (x, y) in the map CRS; fields id (integer), x, y, z, dbh (real, metres; null when unknown), then
// one field per attribute name of any row, null attributes included (in the order given, else in
// name order; named as
// ExportedAttributes in tree_columns.h says, GeoPackage's fid and geom renamed attr_fid, attr_geom;
// null where a row has no value): Integer64 when every value is an integer ("62", not "062"), Real
// when every one is a number in the form read back ("14.9", not "14.90"), else String. Text is
// UTF-8 (shapefiles: with a .cpg saying so). A map without a CRS is written without one
// (GeoPackage: the "Undefined Cartesian SRS", srs_id -1; GeoJSON: "crs": null).
//
// Reading takes the layer --layer names, else the only layer, else the only one with points; the
// point's x and y (and z when the geometry has one) and the fields by name as tree_columns.h
// resolves them (--columns and --dbh-unit apply to field names); a null or unset field is a null
// attribute, a real field's text is FormatReal's (geo_io_internal.h). A GeoPackage's undefined
// SRS (srs_id 0, -1) is no CRS, as is a GeoJSON file's "crs": null, and its default WGS 84 (no
// "crs" member) when its coordinates are not longitude and latitude. Text must be UTF-8; a
// shapefile needs its .dbf.
//
// Errors are CsvError (the tree-file error type) naming the file and, where there is one, the
// feature and field: "FILE: feature 3: field 'dbh': ...". A failed write leaves the file as it
// was: everything is written to a temporary file (a shapefile: directory) beside it and renamed
// into place when complete.

#include <cstdint>
#include <functional>
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

// Writes `rows` in `format` (not kCsv) to `path` as layer `layer`: in a GeoPackage that exists,
// replacing only a layer of that name (the other layers stay); else replacing the file (a
// shapefile: its parts, an old .prj or .cpg included). `crs` is the map's CRS as stored (EPSG:n,
// WKT or PROJ string); empty: none. Returns warnings for the user: fields a shapefile renamed
// (its names have 10 characters). `attribute_order`: the order of the attribute fields
// (ExportedAttributes in tree_columns.h).
// `progress(written, total)` is called after each feature when given.
using GeoWriteProgress = std::function<void(int64_t written, int64_t total)>;
std::vector<std::string> WriteGeoTrees(const std::string& path, TreeFormat format,
                                       const std::vector<MapTreeRow>& rows, const std::string& crs,
                                       const std::string& layer = "trees",
                                       const GeoWriteProgress& progress = {},
                                       const std::vector<std::string>& attribute_order = {});

struct GeoTrees {
  std::vector<MapTreeRow> rows;
  std::string crs_wkt;              // the layer's CRS as WKT; empty when it has none
  std::vector<std::string> fields;  // the layer's field names, in order
};

// Reads the trees' layer of a GIS file (any vector format GDAL opens; options.layer).
GeoTrees ReadGeoTrees(const std::string& path, const TreeFileOptions& options);

}  // namespace forestmap::client
