// `forestmap map create|build|list|show|delete|export|history|restore|remove-source`.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "algorithms/mapping/map_builder.h"
#include "client/cli/cli_boundary.h"
#include "client/cli/cli_commands.h"
#include "client/cli/cli_format.h"
#include "client/cli/cli_tree_crs.h"
#include "client/cli/cli_tree_input.h"
#include "client/io/file_replace.h"
#include "client/io/geo_io.h"
#include "client/io/tree_csv.h"
#include "geo/crs.h"

namespace forestmap::client {
namespace {

struct CreateOptions {
  std::string name;
  std::string trees_file;
  std::string crs;
  std::string to_crs;  // --to-crs: reproject the trees into this CRS, the map's
  std::string description;
  std::string columns;   // --columns x=HEADER,... (io/tree_columns.h)
  std::string dbh_unit;  // --dbh-unit m|cm|mm; empty: from the header, else m
  std::string layer;     // --layer: a GIS file's layer; empty: the only one with points
  std::string boundary_file, boundary_layer;  // --boundary, --boundary-layer
};

// Creates the map with `rows` (from `source`) in one upload stream: the server creates the map
// in the transaction that commits its trees, so a failed or killed upload leaves no map.
void CreateWithTrees(const CreateOptions& options, const std::vector<MapTreeRow>& rows,
                     const std::string& source, const CliContext& context,
                     const std::optional<Boundary>& boundary = std::nullopt,
                     const std::vector<std::string>& columns = {}) {
  ForestMapClient client = context.Connect();
  v1::Map map;
  if (rows.empty() && !boundary) {
    map = client.CreateMap(options.name, options.description, options.crs);
  } else {
    try {
      map = client
                .CreateMapWithTrees(options.name, options.description, options.crs, rows,
                                    UploadProgressTo(*context.err, std::ssize(rows),
                                                     ClientOptions().upload_chunk_trees),
                                    boundary, columns)
                .map();
    } catch (const std::exception& upload_error) {
      throw CommandError("creating map '" + options.name + "' with the trees of " + source +
                         " failed: " + upload_error.what() + "; no map was created");
    }
  }
  *context.out << "created map '" << map.name() << "' (" << map.tree_count() << " trees, version "
               << map.version() << ")" << std::endl;
}

void RunCreate(CreateOptions options, const CliContext& context) {
  std::vector<MapTreeRow> rows;
  std::vector<std::string> columns;  // the file's attribute columns, in its order
  // Read the file before touching the server, so that a bad file leaves nothing behind.
  if (!options.trees_file.empty()) {
    TreeFile file = ReadTreeFile(
        options.trees_file, TreeFileOptionsFrom(options.columns, options.dbh_unit, options.layer));
    rows = std::move(file.rows);
    columns = std::move(file.attribute_columns);
    options.crs = CrsOfTrees(options.trees_file, options.crs, file.crs);
    options.crs =
        ReprojectTrees(rows, options.trees_file, options.crs, options.to_crs, *context.err);
    CheckTreePlacement(rows, options.trees_file, options.crs, *context.err);
  } else if (!options.to_crs.empty()) {
    throw CommandError("--to-crs reprojects the trees of --trees FILE; without trees give --crs");
  }
  if (!options.trees_file.empty() && rows.empty()) {
    *context.err << "forestmap: warning: " << options.trees_file
                 << " has no trees; the map is empty" << std::endl;
  }
  const std::optional<Boundary> boundary = BoundaryForMap(
      options.boundary_file, options.boundary_layer, options.name, options.crs, *context.err);
  CreateWithTrees(options, rows,
                  options.trees_file.empty() ? options.boundary_file : options.trees_file, context,
                  boundary, columns);
}

void AddCreate(CLI::App& map_app, CliContext& context) {
  auto options = std::make_shared<CreateOptions>();
  CLI::App* sub = map_app.add_subcommand(
      "create", "Create a map, empty or with the trees of a CSV file (x,y[,z,dbh,id,...])");
  sub->add_option("NAME", options->name,
                  "Map name: 1-128 characters of A-Z a-z 0-9 _ . - (not . or ..)")
      ->required();
  sub->add_option("--trees", options->trees_file,
                  "The map's trees: CSV (columns x,y (m) required; z, dbh (m), id optional; "
                  "other columns are kept as attributes), or .gpkg / .geojson / .shp points "
                  "(whose CRS is used when --crs is not given)");
  AddTreeFileOptions(*sub, options->columns, options->dbh_unit, &options->layer);
  sub->add_option("--crs", options->crs,
                  "Coordinate reference system of the trees and the map: EPSG code (EPSG:2959), "
                  "WKT or PROJ string, in metres");
  AddToCrsOption(*sub, options->to_crs);
  sub->add_option("--description", options->description, "Free text");
  AddBoundaryOptions(*sub, options->boundary_file, options->boundary_layer);
  sub->callback(
      [options, &context] { context.run = [options, &context] { RunCreate(*options, context); }; });
}

struct BuildOptions {
  CreateOptions map;  // name, crs, description of the new map
  std::string frames_file;
  std::string odometry_file;
  std::string poses_out;
};

// Maps an unknown forest here, on the client (algorithms/mapping/map_builder.h), then uploads the
// confirmed trees as a new map. The first frame defines the map frame.
void RunBuild(const BuildOptions& options, const CliContext& context) {
  const std::vector<Frame> frames = ReadFramesCsv(options.frames_file);
  if (frames.empty()) throw CommandError(options.frames_file + ": no frames (header only)");
  OdometryFromPoses odometry(options.odometry_file);
  try {  // fail before the (long) build, not after it
    context.Connect().GetMap(options.map.name);
    throw CommandError("map '" + options.map.name + "' already exists; choose another name");
  } catch (const RpcError& error) {
    if (error.code() != grpc::StatusCode::NOT_FOUND) throw;
  }

  algorithms::MapBuilder builder;
  int fixes[5] = {0, 0, 0, 0, 0};  // by FrameFix
  for (size_t i = 0; i < frames.size(); ++i) {
    algorithms::BuilderFrame frame;
    frame.frame_id = frames[i].frame;
    frame.trees = frames[i].trees;
    frame.odometry = odometry.Next(frame.frame_id);
    ++fixes[static_cast<int>(builder.AddFrame(frame).fix)];
    if ((i + 1) % 100 == 0 || i + 1 == frames.size()) {
      *context.err << "map build: " << i + 1 << "/" << frames.size() << " frames, "
                   << builder.map().size() << " trees, " << builder.loop_closures()
                   << " loop closures" << std::endl;
    }
  }
  builder.Finish();
  *context.err << "map build: " << fixes[static_cast<int>(algorithms::FrameFix::kTracked)]
               << " frames tracked, "
               << fixes[static_cast<int>(algorithms::FrameFix::kRelocalized)] +
                      fixes[static_cast<int>(algorithms::FrameFix::kGlobal)]
               << " relocalized, " << fixes[static_cast<int>(algorithms::FrameFix::kDeadReckoned)]
               << " without a fix (not merged)" << std::endl;

  if (!options.poses_out.empty()) {
    std::ofstream out(options.poses_out);
    out << "frame,timestamp,x,y,z,qx,qy,qz,qw\n" << std::setprecision(10);
    const std::vector<algorithms::Pose3> poses = builder.Poses();
    for (size_t i = 0; i < poses.size(); ++i) {
      const Eigen::Quaterniond q(poses[i].linear());
      const Eigen::Vector3d t = poses[i].translation();
      out << frames[i].frame << ',' << i << ',' << t.x() << ',' << t.y() << ',' << t.z() << ','
          << q.x() << ',' << q.y() << ',' << q.z() << ',' << q.w() << '\n';
    }
    if (!out) throw CommandError(options.poses_out + ": cannot write the poses");
  }
  std::vector<MapTreeRow> rows;
  for (const algorithms::MapTree& tree : builder.ConfirmedTrees()) {
    MapTreeRow row;
    row.x = tree.position.x();
    row.y = tree.position.y();
    if (std::isfinite(tree.position.z())) row.z = tree.position.z();
    if (std::isfinite(tree.dbh)) row.dbh = tree.dbh;
    rows.push_back(row);
  }
  CreateWithTrees(options.map, rows, "the built map", context);
}

void AddBuild(CLI::App& map_app, CliContext& context) {
  auto options = std::make_shared<BuildOptions>();
  CLI::App* sub = map_app.add_subcommand(
      "build",
      "Map an unknown forest from a drone's frames alone (tree SLAM with loop closure, on this "
      "machine), then create the map with the confirmed trees; the first frame defines the map "
      "frame");
  sub->add_option("NAME", options->map.name, "New map's name")->required();
  sub->add_option("--frames", options->frames_file,
                  "CSV of the frames' detected trees (frame,x,y,...; sensor frame), in order")
      ->required()
      ->check(CLI::ExistingFile);
  sub->add_option("--odometry", options->odometry_file,
                  "Poses CSV (frame,timestamp,x,y,z,qx,qy,qz,qw) in any world frame: the motion "
                  "between consecutive frames is used as odometry")
      ->check(CLI::ExistingFile);
  sub->add_option("--poses-out", options->poses_out,
                  "Write the built trajectory (map_from_sensor per frame) to this CSV");
  sub->add_option("--description", options->map.description, "Free text");
  sub->callback(
      [options, &context] { context.run = [options, &context] { RunBuild(*options, context); }; });
}

struct ExportOptions {
  std::string name;
  std::string out_file;  // empty or "-": stdout
  int64_t version = 0;   // 0: current
  std::string format;    // csv|geojson|gpkg|shp; empty: from the extension of out_file
  std::string to_crs;    // --to-crs: the trees reprojected into this CRS; empty: the map's
};

// --to-crs: `rows` moved from the map's CRS into `to` (any CRS, degrees too: EPSG:4326 for web
// tools). Returns `to`.
std::string ReprojectExport(std::vector<MapTreeRow>& rows, const v1::Map& map,
                            const std::string& to) {
  if (map.crs().empty()) {
    throw CommandError("--to-crs: map '" + map.name() + "' has no CRS to reproject from");
  }
  try {
    const geo::Reprojection move(map.crs(), to);
    for (MapTreeRow& row : rows) {
      double z = row.z.value_or(0);  // heights are kept as they are
      move.Apply(row.x, row.y, z);
    }
  } catch (const geo::CrsError& e) {
    throw CommandError(std::string("--to-crs ") + to + ": " + e.what());
  }
  return to;
}

// Shared maps: the state of each tree as extra columns (status, observations, sigmas), added
// only when some tree came from observations, so survey exports keep their columns.
void AddStateColumns(ExportedTrees& exported) {
  const bool observed = std::any_of(exported.states.begin(), exported.states.end(),
                                    [](const TreeState& s) { return s.observations > 0; });
  if (!observed) return;
  const auto number = [](const std::optional<double>& v) {
    if (!v) return std::string();
    char buffer[32];
    std::snprintf(buffer, sizeof(buffer), "%.4f", *v);
    return std::string(buffer);
  };
  for (size_t i = 0; i < exported.trees.size(); ++i) {
    const TreeState& state = exported.states[i];
    auto& attributes = exported.trees[i].attributes;
    attributes["status"] = state.confirmed ? "confirmed" : "candidate";
    attributes["observations"] = std::to_string(state.observations);
    if (state.position_sigma_m) attributes["position_sigma_m"] = number(state.position_sigma_m);
    if (state.dbh_sigma_m) attributes["dbh_sigma_m"] = number(state.dbh_sigma_m);
    if (state.last_seen_unix_ms) attributes["last_seen"] = FormatUnixMs(*state.last_seen_unix_ms);
  }
}

// --format, or the --out extension's. An extension that names another format is refused (a
// shapefile is always FILE.shp: GDAL would make a directory of any other name), and so is one
// that names no format we write (x.kml would silently be CSV); no extension at all is CSV.
TreeFormat ExportFormat(const ExportOptions& options) {
  const TreeFormat by_extension = TreeFormatOfPath(options.out_file);
  const std::string extension = LowerExtension(options.out_file);
  const bool known = by_extension != TreeFormat::kCsv || extension == ".csv";
  if (options.format.empty()) {
    if (!known && !extension.empty()) {
      throw CommandError("--out " + options.out_file + ": forestmap writes no '" + extension +
                         "' files; name it .csv, .geojson, .gpkg or .shp (or give --format)");
    }
    return by_extension;
  }
  const TreeFormat format = ParseTreeFormat(options.format);
  if ((known && by_extension != format) || (format == TreeFormat::kShapefile && !known)) {
    throw CommandError("--format " + options.format + " and --out " + options.out_file +
                       " disagree: name the file " +
                       std::filesystem::path(options.out_file).replace_extension("").string() +
                       "." + (format == TreeFormat::kGeoJson ? "geojson" : options.format));
  }
  return format;
}

// Trees of the exported version, for the progress lines (0: unknown).
int64_t TreesToExport(ForestMapClient& client, const v1::Map& map, int64_t version) {
  if (version == 0 || version == map.version()) return map.tree_count();
  for (const v1::MapVersion& listed : client.ListVersions(map.name())) {
    if (listed.version() == version) return listed.tree_count();
  }
  return 0;
}

// The trees of map `name` to `out_file` (not standard output) in `format`, with CRS `crs`.
// The attribute columns in the map's order (ExportedTrees::attribute_columns).
void WriteExportFile(const std::string& out_file, TreeFormat format, const ExportedTrees& exported,
                     const std::string& crs, const std::string& name, std::ostream& err) {
  const std::vector<MapTreeRow>& trees = exported.trees;
  const std::vector<std::string>& order = exported.attribute_columns;
  if (format == TreeFormat::kCsv) {
    ReplaceFile(out_file,
                [&](const std::string& temporary) { WriteMapTreesCsv(temporary, trees, order); });
    // The CRS as WKT beside the CSV, as GIS tools keep it (map create --trees reads it back);
    // for a map without one, an old .prj is removed.
    WriteCrsSidecar(out_file, crs);
    return;
  }
  // A GeoPackage takes the map as its layer (others stay); other formats are replaced.
  const auto written = ProgressTo(err, "writing " + out_file, std::ssize(trees), kExportChunk);
  for (const std::string& warning : WriteGeoTrees(
           out_file, format, trees, crs, name,
           written ? [&written](int64_t done, int64_t) { written(done); } : GeoWriteProgress(),
           order)) {
    err << "forestmap: warning: " << warning << std::endl;
  }
}

void RunExport(const ExportOptions& options, const CliContext& context) {
  const bool to_stdout = options.out_file.empty() || options.out_file == "-";
  if (to_stdout && !options.format.empty() && options.format != "csv") {
    throw CommandError("--format " + options.format + " needs --out FILE");
  }
  // Checked before the download.
  const TreeFormat format = to_stdout ? TreeFormat::kCsv : ExportFormat(options);
  std::string out_file = options.out_file;
  // GDAL writes a shapefile's parts in lower case: t.SHP is written (and reported) as t.shp.
  if (format == TreeFormat::kShapefile) {
    out_file = std::filesystem::path(out_file).replace_extension(".shp").string();
  }
  if (!to_stdout) CheckNoSidecarClash(out_file, format);
  if (!options.to_crs.empty()) {
    try {
      geo::ParseCrs(options.to_crs);
    } catch (const geo::CrsError& e) {
      throw CommandError(std::string("--to-crs ") + options.to_crs + ": " + e.what());
    }
  }
  ForestMapClient client = context.Connect();
  const v1::Map map = client.GetMap(options.name);
  const int64_t total = TreesToExport(client, map, options.version);
  ExportedTrees exported =
      client.ExportTrees(options.name, std::nullopt, options.version,
                         ProgressTo(*context.err, "exporting", total, kExportChunk));
  AddStateColumns(exported);
  const std::string crs =
      options.to_crs.empty() ? map.crs() : ReprojectExport(exported.trees, map, options.to_crs);
  if (!exported.boundary.empty() && format == TreeFormat::kCsv) {
    *context.err << "forestmap: warning: map '" << options.name
                 << "' has a survey boundary, which a CSV cannot hold: export to .gpkg or "
                    ".geojson to keep it"
                 << std::endl;
  }
  if (to_stdout) {
    WriteMapTreesCsv(*context.out, exported.trees, exported.attribute_columns);
    context.out->flush();
    if (!*context.out) throw CommandError("writing to standard output failed");
    return;
  }
  WriteExportFile(out_file, format, exported, crs, options.name, *context.err);
  *context.err << "exported " << exported.trees.size() << " trees of map '" << options.name
               << "' (version " << exported.map_version << ") to " << out_file;
  if (format == TreeFormat::kGeoPackage) *context.err << " (layer '" << options.name << "')";
  if (!exported.boundary.empty() && format != TreeFormat::kCsv) {
    *context.err << ", "
                 << ExportBoundary(exported.boundary, out_file, format, map, options.to_crs, crs);
  }
  *context.err << std::endl;
}

void AddExport(CLI::App& map_app, CliContext& context) {
  auto options = std::make_shared<ExportOptions>();
  CLI::App* sub =
      map_app.add_subcommand("export",
                             "Write a map's trees as CSV (id,x,y,z,dbh,<attributes>), GeoJSON, "
                             "GeoPackage or shapefile (points with the map's CRS), and its survey "
                             "boundary beside them: a GeoPackage's layer 'boundary', else the "
                             "file NAME.boundary.geojson / .shp next to --out");
  sub->add_option("NAME", options->name, "Map name")->required();
  sub->add_option("--out", options->out_file, "Output file (default: CSV on standard output)");
  sub->add_option("--format", options->format,
                  "csv, geojson, gpkg or shp (default: from the --out extension, else csv)")
      ->check(CLI::IsMember({"csv", "geojson", "gpkg", "shp"}));
  sub->add_option("--to-crs", options->to_crs,
                  "Reproject the trees into this CRS (EPSG:n, WKT or PROJ), e.g. EPSG:4326: a "
                  "GeoJSON in WGS 84 is written as RFC 7946, as web tools expect");
  sub->add_option("--version", options->version,
                  "Map version to export (default 0: the current one; see 'map history')")
      ->check(CLI::NonNegativeNumber);
  sub->callback(
      [options, &context] { context.run = [options, &context] { RunExport(*options, context); }; });
}

void AddRestore(CLI::App& map_app, CliContext& context) {
  auto name = std::make_shared<std::string>();
  auto version = std::make_shared<int64_t>(0);
  CLI::App* sub = map_app.add_subcommand(
      "restore", "Make a new version whose trees equal those of an older version");
  sub->add_option("NAME", *name, "Map name")->required();
  sub->add_option("VERSION", *version, "The version to bring back (see 'map history')")
      ->required()
      ->check(CLI::PositiveNumber);
  sub->callback([name, version, &context] {
    context.run = [name, version, &context] {
      const v1::Map map = context.Connect().RestoreVersion(*name, *version);
      *context.out << "restored map '" << map.name() << "' to the trees of version " << *version
                   << " as version " << map.version() << " (" << map.tree_count() << " trees)"
                   << std::endl;
    };
  });
}

void AddRemoveSource(CLI::App& map_app, CliContext& context) {
  auto name = std::make_shared<std::string>();
  auto source = std::make_shared<std::string>();
  CLI::App* sub = map_app.add_subcommand(
      "remove-source",
      "Remove every observation of one source (drone) and recompute the trees it touched");
  sub->add_option("NAME", *name, "Map name")->required();
  sub->add_option("SOURCE", *source, "The source id given to 'observe --source'")->required();
  sub->callback([name, source, &context] {
    context.run = [name, source, &context] {
      const v1::RemoveSourceResponse r = context.Connect().RemoveSource(*name, *source);
      *context.out << "removed " << r.observations_removed() << " observations of '" << *source
                   << "' from map '" << *name << "': " << r.trees_updated() << " trees recomputed, "
                   << r.trees_removed() << " removed; version " << r.map().version() << " ("
                   << r.map().tree_count() << " trees)" << std::endl;
    };
  });
}

}  // namespace

void AddMapCommand(CLI::App& app, CliContext& context) {
  CLI::App* map_app = app.add_subcommand(
      "map",
      "Create, upload into, build, list, show, delete and export maps; history, changes, "
      "restore, remove-source, prune");
  AddCreate(*map_app, context);
  AddMapUploadCommand(*map_app, context);
  AddBuild(*map_app, context);
  AddMapListingCommands(*map_app, context);
  AddMapChangesCommand(*map_app, context);
  AddExport(*map_app, context);
  AddRestore(*map_app, context);
  AddRemoveSource(*map_app, context);
  AddMapPruneCommand(*map_app, context);
}

}  // namespace forestmap::client
