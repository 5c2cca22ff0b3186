#include "client/cli/cli_tree_input.h"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <optional>
#include <stdexcept>

#include "client/cli/cli_context.h"
#include "client/io/file_replace.h"
#include "client/io/geo_io.h"
#include "geo/crs.h"

namespace forestmap::client {

void AddTreeFileOptions(CLI::App& command, std::string& columns, std::string& dbh_unit,
                        std::string* layer) {
  command.add_option("--columns", columns,
                     "Which file columns are the tree's, when their names are not x, y, z, dbh, "
                     "id: e.g. x=Field_Xpj,y=Field_Ypj,dbh=DBH,id=Tree (any subset); other "
                     "columns are kept as attributes");
  command.add_option("--dbh-unit", dbh_unit,
                     "Unit of the DBH column: m, cm, mm or in (default: from a _cm/_mm/_in "
                     "suffix of its name, else m)");
  if (layer) {
    command.add_option("--layer", *layer,
                       "GIS files with several layers (GeoPackage): the trees' layer (default: "
                       "the only layer with points)");
  }
}

TreeFileOptions TreeFileOptionsFrom(const std::string& columns, const std::string& dbh_unit,
                                    const std::string& layer, const std::string& flags) {
  TreeFileOptions options;
  options.layer = layer;
  options.columns_flag = flags + "columns";
  options.dbh_unit_flag = flags + "dbh-unit";
  try {
    if (!columns.empty()) options.columns = ParseColumnMapping(columns, options.columns_flag);
    if (!dbh_unit.empty()) options.dbh_unit = ParseDbhUnit(dbh_unit, options.dbh_unit_flag);
    options.notes = &std::cerr;  // text ids kept as attributes
  } catch (const std::invalid_argument& e) {
    throw CommandError(e.what());
  }
  return options;
}

namespace {

// The CRS in FILE.prj or FILE.PRJ beside a CSV (empty: none); one PROJ does not know is an error
// naming the .prj, not the CSV.
std::string ReadCrsSidecar(const std::string& csv_path) {
  const std::optional<std::string> prj = FindSidecar(csv_path, ".prj");
  if (!prj) return "";
  std::ifstream in(*prj);
  std::string crs((std::istreambuf_iterator<char>(in)), {});
  if (!in && !in.eof()) throw CommandError(*prj + ": cannot read");
  while (!crs.empty() && std::isspace(static_cast<unsigned char>(crs.back()))) crs.pop_back();
  if (crs.empty()) return crs;
  try {
    geo::ParseCrs(crs);
  } catch (const geo::CrsError& e) {
    throw CommandError(*prj + ": not a CRS PROJ knows (" + std::string(e.what()) +
                       "); it should hold the WKT or EPSG code of " + csv_path +
                       "'s CRS, or be removed");
  }
  return crs;
}

}  // namespace

TreeFile ReadTreeFile(const std::string& path, const TreeFileOptions& options) {
  TreeFile file;
  if (TreeFormatOfPath(path) == TreeFormat::kCsv) {
    std::vector<std::string> header;
    file.rows = ReadMapTreesCsv(path, options, &header);
    file.crs = ReadCrsSidecar(path);
    file.attribute_columns = AttributeColumnOrder(header, file.rows);
    return file;
  }
  GeoTrees trees = ReadGeoTrees(path, options);
  file.rows = std::move(trees.rows);
  file.crs = std::move(trees.crs_wkt);
  file.attribute_columns = AttributeColumnOrder(trees.fields, file.rows);
  return file;
}

std::string LowerExtension(const std::filesystem::path& path) {
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return extension;
}

// A sidecar file of one export must not replace another's: a CSV's CRS goes to FILE.prj, which
// is also a part of the shapefile FILE.shp (and the other way round).
void CheckNoSidecarClash(const std::filesystem::path& out, TreeFormat format) {
  if (format != TreeFormat::kCsv && format != TreeFormat::kShapefile) return;
  const std::string other = format == TreeFormat::kCsv ? ".shp" : ".csv";
  std::error_code error;
  const std::filesystem::path folder = out.has_parent_path() ? out.parent_path() : ".";
  for (const auto& entry : std::filesystem::directory_iterator(folder, error)) {
    if (entry.path().stem() == out.stem() && LowerExtension(entry.path()) == other) {
      throw CommandError("--out " + out.string() + ": its CRS file " +
                         std::filesystem::path(out).replace_extension(".prj").string() +
                         " would replace that of " + entry.path().string() +
                         "; export to another name or folder");
    }
  }
}

void WriteCrsSidecar(const std::string& csv_path, const std::string& crs) {
  try {
    RemoveSidecars(csv_path, {".prj"});  // an old one (h.prj, h.PRJ) would tell another CRS
  } catch (const CsvError& e) {
    throw CommandError(e.what());
  }
  if (crs.empty()) return;
  const std::string path = std::filesystem::path(csv_path).replace_extension(".prj").string();
  std::string wkt = crs;  // a .prj holds WKT, never "EPSG:n" (a LAS file's GeoKeys give that)
  try {
    wkt = geo::ParseCrs(crs).wkt;
  } catch (const geo::CrsError&) {
    // Not a CRS PROJ knows: written as it came, for the user to see.
  }
  std::ofstream out(path);
  out << wkt << '\n';
  if (!out) throw CommandError(path + ": cannot write the CRS");
}

std::string ShortCrs(const std::string& crs) {
  const size_t open = crs.find('"');
  const size_t close = open == std::string::npos ? open : crs.find('"', open + 1);
  if (crs.rfind("EPSG:", 0) == 0 || close == std::string::npos) return crs.substr(0, 64);
  return crs.substr(open + 1, close - open - 1);
}

}  // namespace forestmap::client
