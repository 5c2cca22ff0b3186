#pragma once
// Tree inventories as commands read them: --columns and --dbh-unit (io/tree_columns.h), and the
// file format chosen by extension (CSV, or GeoPackage / GeoJSON / shapefile through GDAL).

#include <CLI/CLI.hpp>
#include <filesystem>
#include <string>
#include <vector>

#include "client/io/geo_io.h"
#include "client/io/tree_columns.h"
#include "client/io/tree_csv.h"

namespace forestmap::client {

// Adds --columns and --dbh-unit (and, given `layer`, --layer) to `command`, storing their text.
void AddTreeFileOptions(CLI::App& command, std::string& columns, std::string& dbh_unit,
                        std::string* layer = nullptr);

// The options from their text; throws CommandError naming the flag.
// `flags` is the prefix of the flags messages name: "--" (--columns, --dbh-unit), or
// "--reference-" for compare's reference.
TreeFileOptions TreeFileOptionsFrom(const std::string& columns, const std::string& dbh_unit,
                                    const std::string& layer = "", const std::string& flags = "--");

// A tree file and the CRS it declares (empty when it declares none, as CSV never does).
struct TreeFile {
  std::vector<MapTreeRow> rows;
  std::string crs;                             // WKT
  std::vector<std::string> attribute_columns;  // in the file's order (AttributeColumnOrder)
};

// Reads CSV (any other extension) or, by extension, .gpkg, .geojson/.json, .shp. A CSV's CRS is
// the WKT or EPSG code in FILE.prj (or FILE.PRJ) beside it, when there is one
// (io/crs_sidecar.h).
TreeFile ReadTreeFile(const std::string& path, const TreeFileOptions& options);

// Writes `crs` as WKT to PATH.prj (PATH without its extension), beside a CSV, replacing any
// PATH.prj or PATH.PRJ; an empty `crs` (none) removes them and writes nothing.
void WriteCrsSidecar(const std::string& csv_path, const std::string& crs);

// A file's extension in lower case (".shp").
std::string LowerExtension(const std::filesystem::path& path);

// Throws CommandError when writing `out` in `format` would replace a file of another export: a
// CSV's CRS sidecar FILE.prj is also a part of the shapefile FILE.shp, and the other way round.
// Called before anything is written.
void CheckNoSidecarClash(const std::filesystem::path& out, TreeFormat format);

// "EPSG:n", or the name in a WKT's first quotes, for messages.
std::string ShortCrs(const std::string& crs);

}  // namespace forestmap::client
