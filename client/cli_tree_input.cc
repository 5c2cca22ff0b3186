#include "client/cli_tree_input.h"

#include <stdexcept>

#include "client/cli_commands.h"
#include "client/io/geo_io.h"

namespace forestmap::client {

void AddTreeFileOptions(CLI::App& command, std::string& columns, std::string& dbh_unit) {
  command.add_option("--columns", columns,
                     "Which file columns are the tree's, when their names are not x, y, z, dbh, "
                     "id: e.g. x=Field_Xpj,y=Field_Ypj,dbh=DBH,id=Tree (any subset); other "
                     "columns are kept as attributes");
  command.add_option("--dbh-unit", dbh_unit,
                     "Unit of the DBH column: m, cm or mm (default: from a _cm/_mm suffix of "
                     "its name, else m)");
}

TreeFileOptions TreeFileOptionsFrom(const std::string& columns, const std::string& dbh_unit) {
  TreeFileOptions options;
  try {
    if (!columns.empty()) options.columns = ParseColumnMapping(columns);
    if (!dbh_unit.empty()) options.dbh_unit = ParseDbhUnit(dbh_unit);
  } catch (const std::invalid_argument& e) {
    throw CommandError(e.what());
  }
  return options;
}

TreeFile ReadTreeFile(const std::string& path, const TreeFileOptions& options) {
  TreeFile file;
  if (TreeFormatOfPath(path) == TreeFormat::kCsv) {
    file.rows = ReadMapTreesCsv(path, options);
    return file;
  }
  GeoTrees trees = ReadGeoTrees(path, options);
  file.rows = std::move(trees.rows);
  file.crs = std::move(trees.crs_wkt);
  return file;
}

}  // namespace forestmap::client
