// `forestmap map upload`: a tree file into an existing map, appended or replacing its trees, in
// one upload stream (the server applies it in one transaction: all or nothing).

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "client/cli/cli_boundary.h"
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
  std::string boundary_file, boundary_layer;  // --boundary, --boundary-layer
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
  if (options.trees_file.empty() && options.boundary_file.empty()) {
    throw CommandError("give --trees FILE, --boundary FILE or both");
  }
  if (options.trees_file.empty() && options.replace) {
    throw CommandError("--replace replaces the map's trees by those of --trees FILE");
  }
  // Read and check the files before writing anything.
  TreeFile file;
  if (!options.trees_file.empty()) {
    file = ReadTreeFile(options.trees_file,
                        TreeFileOptionsFrom(options.columns, options.dbh_unit, options.layer));
  }
  ForestMapClient client = context.Connect();
  const v1::Map map = client.GetMap(options.name);
  if (!options.trees_file.empty()) {
    try {
      PlaceInMap(file.rows, options, CrsOfTrees(options.trees_file, options.crs, file.crs),
                 map.crs(), *context.err);
    } catch (const geo::CrsError& e) {
      throw CommandError(options.trees_file + ": " + e.what());
    }
    CheckTreePlacement(file.rows, options.trees_file, map.crs(), *context.err);
  }
  // Without --boundary the map keeps the one it has.
  const std::optional<Boundary> boundary = BoundaryForMap(
      options.boundary_file, options.boundary_layer, options.name, map.crs(), *context.err);
  const std::string what = options.trees_file.empty() ? "the boundary of " + options.boundary_file
                                                      : "the trees of " + options.trees_file;
  v1::UploadTreesResponse response;
  try {
    response = client.UploadTrees(
        options.name, file.rows, options.replace,
        UploadProgressTo(*context.err, std::ssize(file.rows), ClientOptions().upload_chunk_trees),
        boundary, file.attribute_columns);
  } catch (const std::exception& upload_error) {
    throw CommandError("uploading " + what + " to map '" + options.name +
                       "' failed: " + upload_error.what() + "; the map is unchanged");
  }
  *context.out << (options.replace ? "replaced the trees of" : "appended to") << " map '"
               << options.name << "': " << response.trees_received() << " trees uploaded, "
               << response.map().tree_count() << " trees, version " << response.map().version();
  if (boundary) *context.out << ", survey boundary of " << boundary->size() << " polygons";
  *context.out << std::endl;
}

}  // namespace

void AddMapUploadCommand(CLI::App& map_app, CliContext& context) {
  auto options = std::make_shared<UploadOptions>();
  CLI::App* sub = map_app.add_subcommand(
      "upload",
      "Add the trees of a file to an existing map (or --replace its trees) as one new version: "
      "CSV or .gpkg / .geojson / .shp points, reprojected into the map's CRS when theirs "
      "differs; with --boundary, the map's survey boundary too (or alone)");
  sub->add_option("NAME", options->name, "Map name")->required();
  sub->add_option("--trees", options->trees_file,
                  "The trees: CSV (columns x,y (m) required; z, dbh (m), id optional; other "
                  "columns are kept as attributes), or .gpkg / .geojson / .shp points");
  AddTreeFileOptions(*sub, options->columns, options->dbh_unit, &options->layer);
  sub->add_option("--crs", options->crs,
                  "CRS of the trees (EPSG code, WKT or PROJ string) when the file declares none; "
                  "trees in another CRS than the map's are reprojected into it");
  sub->add_flag("--replace", options->replace,
                "Replace the map's trees by the file's (default: append; trees without an id get "
                "new ones)");
  AddBoundaryOptions(*sub, options->boundary_file, options->boundary_layer);
  sub->callback(
      [options, &context] { context.run = [options, &context] { RunUpload(*options, context); }; });
}

}  // namespace forestmap::client
