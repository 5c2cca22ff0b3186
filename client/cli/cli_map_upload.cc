// `forestmap map upload`: a tree file into an existing map, appended or replacing its trees, in
// one upload stream (the server applies it in one transaction: all or nothing).

#include <memory>
#include <string>
#include <vector>

#include "client/cli/cli_commands.h"
#include "client/cli/cli_format.h"
#include "client/cli/cli_tree_crs.h"
#include "client/cli/cli_tree_input.h"
#include "geo/crs.h"

namespace forestmap::client {
namespace {

struct UploadOptions {
  std::string name;
  std::string trees_file;
  std::string crs;       // the trees' CRS when the file declares none
  std::string columns;   // --columns x=HEADER,... (io/tree_columns.h)
  std::string dbh_unit;  // --dbh-unit m|cm|mm
  std::string layer;     // --layer: a GIS file's layer; empty: the only one with points
  bool replace = false;
};

// The trees into the map's CRS: reprojected when they are in another, refused when they are in
// degrees or feet and the map has no CRS to take them to.
void PlaceInMap(std::vector<MapTreeRow>& rows, const UploadOptions& options,
                const std::string& from, const std::string& map_crs, std::ostream& log) {
  if (from.empty()) return;  // taken to be in the map's frame, as a CSV without .prj is
  if (map_crs.empty()) {
    const geo::CrsInfo info = geo::ParseCrs(from);
    if (!info.map_problem.empty()) {
      throw CommandError(options.trees_file + ": its CRS " + DescribedCrs(from) +
                         " cannot be a map's: " + info.map_problem + ", and map '" + options.name +
                         "' has no CRS to reproject the trees into");
    }
    log << "forestmap: warning: map '" << options.name << "' has no CRS; the trees of "
        << options.trees_file << " (" << DescribedCrs(from) << ") are uploaded as they are"
        << std::endl;
    return;
  }
  if (!SameCrs(from, map_crs)) ReprojectTrees(rows, options.trees_file, from, map_crs, log);
}

void RunUpload(const UploadOptions& options, const CliContext& context) {
  // Read and check the file before writing anything.
  TreeFile file = ReadTreeFile(
      options.trees_file, TreeFileOptionsFrom(options.columns, options.dbh_unit, options.layer));
  ForestMapClient client = context.Connect();
  const v1::Map map = client.GetMap(options.name);
  try {
    PlaceInMap(file.rows, options, CrsOfTrees(options.trees_file, options.crs, file.crs), map.crs(),
               *context.err);
  } catch (const geo::CrsError& e) {
    throw CommandError(options.trees_file + ": " + e.what());
  }
  CheckTreePlacement(file.rows, options.trees_file, map.crs(), *context.err);
  v1::UploadTreesResponse response;
  try {
    response = client.UploadTrees(
        options.name, file.rows, options.replace,
        UploadProgressTo(*context.err, std::ssize(file.rows), ClientOptions().upload_chunk_trees));
  } catch (const std::exception& upload_error) {
    throw CommandError("uploading the trees of " + options.trees_file + " to map '" + options.name +
                       "' failed: " + upload_error.what() + "; the map is unchanged");
  }
  *context.out << (options.replace ? "replaced the trees of" : "appended to") << " map '"
               << options.name << "': " << response.trees_received() << " trees uploaded, "
               << response.map().tree_count() << " trees, version " << response.map().version()
               << std::endl;
}

}  // namespace

void AddMapUploadCommand(CLI::App& map_app, CliContext& context) {
  auto options = std::make_shared<UploadOptions>();
  CLI::App* sub = map_app.add_subcommand(
      "upload",
      "Add the trees of a file to an existing map (or --replace its trees) as one new version: "
      "CSV or .gpkg / .geojson / .shp points, reprojected into the map's CRS when theirs differs");
  sub->add_option("NAME", options->name, "Map name")->required();
  sub->add_option("--trees", options->trees_file,
                  "The trees: CSV (columns x,y (m) required; z, dbh (m), id optional; other "
                  "columns are kept as attributes), or .gpkg / .geojson / .shp points")
      ->required();
  AddTreeFileOptions(*sub, options->columns, options->dbh_unit, &options->layer);
  sub->add_option("--crs", options->crs,
                  "CRS of the trees (EPSG code, WKT or PROJ string) when the file declares none; "
                  "trees in another CRS than the map's are reprojected into it");
  sub->add_flag("--replace", options->replace,
                "Replace the map's trees by the file's (default: append; trees without an id get "
                "new ones)");
  sub->callback(
      [options, &context] { context.run = [options, &context] { RunUpload(*options, context); }; });
}

}  // namespace forestmap::client
