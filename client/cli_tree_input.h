#pragma once
// Tree inventories as commands read them: --columns and --dbh-unit (io/tree_columns.h), and the
// file format chosen by extension (CSV, or GeoPackage / GeoJSON / shapefile through GDAL).

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "client/io/tree_columns.h"
#include "client/io/tree_csv.h"

namespace forestmap::client {

// Adds --columns and --dbh-unit to `command`, storing their text.
void AddTreeFileOptions(CLI::App& command, std::string& columns, std::string& dbh_unit);

// The options from their text; throws CommandError naming the flag.
TreeFileOptions TreeFileOptionsFrom(const std::string& columns, const std::string& dbh_unit);

// A tree file and the CRS it declares (empty when it declares none, as CSV never does).
struct TreeFile {
  std::vector<MapTreeRow> rows;
  std::string crs;  // WKT
};

// Reads CSV (any other extension) or, by extension, .gpkg, .geojson/.json, .shp. A CSV's CRS is
// the WKT or EPSG code in FILE.prj beside it, when there is one.
TreeFile ReadTreeFile(const std::string& path, const TreeFileOptions& options);

// Writes `crs` to PATH.prj (PATH without its extension), beside a CSV.
void WriteCrsSidecar(const std::string& csv_path, const std::string& crs);

// Adds --to-crs to `command`, storing its text.
void AddToCrsOption(CLI::App& command, std::string& to_crs);

// Puts `rows`, read from `path` in CRS `from` (the file's own or --crs; empty: unknown), into
// CRS `to` (--to-crs; "utm": the WGS 84 / UTM zone of their centre) and returns the CRS they are
// then in. Only x and y move; heights are kept. Without `to`, a `from` whose coordinates are not
// metres on a plane (degrees, feet) is refused, naming the --to-crs that would take it. Throws
// CommandError naming the file (and the tree PROJ cannot move).
std::string ReprojectTrees(std::vector<MapTreeRow>& rows, const std::string& path,
                           const std::string& from, const std::string& to, std::ostream& log);

// Warns on `log` when the trees of `path` cannot be where `crs` says: closer together than trees
// stand (half of them under 5 cm from their nearest neighbour: x and y are not metres), or their
// centre outside the area of use of `crs` (a wrong CRS).
void CheckTreePlacement(const std::vector<MapTreeRow>& rows, const std::string& path,
                        const std::string& crs, std::ostream& log);

// The CRS of trees read from `path`: --crs (`given`) or the file's own (`declared`); refuses a
// --crs that contradicts the file's CRS (it would relabel the coordinates without moving them).
std::string CrsOfTrees(const std::string& path, const std::string& given,
                       const std::string& declared);

// Whether coordinates in `crs` are metres on a plane (true for an empty, unknown CRS), and
// whether two CRSs are the same; throw CommandError for a CRS PROJ does not know.
bool InMetres(const std::string& crs);
bool SameCrs(const std::string& a, const std::string& b);

// "EPSG:n (name)", or the CRS's name, for messages (ShortCrs when PROJ does not know it).
std::string DescribedCrs(const std::string& crs);

// "EPSG:n", or the name in a WKT's first quotes, for messages.
std::string ShortCrs(const std::string& crs);

}  // namespace forestmap::client
