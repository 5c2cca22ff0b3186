// `forestmap map create|list|show|delete|export`.

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "client/cli_commands.h"
#include "client/cli_format.h"
#include "client/tree_csv.h"

namespace forestmap::client {
namespace {

struct CreateOptions {
  std::string name;
  std::string trees_file;
  std::string crs;
  std::string description;
};

// Uploads in chunks; reports progress on stderr only when there is more than one chunk.
v1::UploadTreesResponse UploadWithProgress(ForestMapClient& client, const std::string& name,
                                           const std::vector<MapTreeRow>& rows, std::ostream& err) {
  const int64_t chunk = ClientOptions().upload_chunk_trees;
  const bool report = static_cast<int64_t>(rows.size()) > chunk;
  return client.UploadTrees(name, rows, /*replace=*/false, [&](int64_t sent, int64_t total) {
    if (report) err << "uploading: " << sent << "/" << total << " trees" << std::endl;
  });
}

void RunCreate(const CreateOptions& options, const CliContext& context) {
  std::vector<MapTreeRow> rows;
  // Read the file before touching the server, so that a bad file leaves nothing behind.
  if (!options.trees_file.empty()) rows = ReadMapTreesCsv(options.trees_file);
  ForestMapClient client = context.Connect();
  v1::Map map = client.CreateMap(options.name, options.description, options.crs);
  if (!options.trees_file.empty() && rows.empty()) {
    *context.err << "forestmap: warning: " << options.trees_file
                 << " has no trees; the map is empty" << std::endl;
  }
  if (!rows.empty()) {
    try {
      map = UploadWithProgress(client, options.name, rows, *context.err).map();
    } catch (const std::exception& upload_error) {
      std::string outcome = "the new map '" + options.name + "' was deleted";
      try {
        client.DeleteMap(options.name);
      } catch (const std::exception& delete_error) {
        outcome = "deleting the new map also failed (" + std::string(delete_error.what()) +
                  "); remove it with 'forestmap map delete " + options.name + "'";
      }
      throw CommandError("uploading " + options.trees_file + " to map '" + options.name +
                         "' failed: " + upload_error.what() + "; " + outcome);
    }
  }
  *context.out << "created map '" << map.name() << "' (" << map.tree_count() << " trees, version "
               << map.version() << ")" << std::endl;
}

void AddCreate(CLI::App& map_app, CliContext& context) {
  auto options = std::make_shared<CreateOptions>();
  CLI::App* sub = map_app.add_subcommand(
      "create", "Create a map, empty or with the trees of a CSV file (x,y[,z,dbh,id,...])");
  sub->add_option("NAME", options->name, "Map name: 1-128 characters of A-Z a-z 0-9 _ . -")
      ->required();
  sub->add_option("--trees", options->trees_file,
                  "CSV of the map's trees: columns x,y (m) required; z, dbh (m), id optional; "
                  "other columns are kept as attributes");
  sub->add_option("--crs", options->crs, "Coordinate reference system, e.g. EPSG:32612");
  sub->add_option("--description", options->description, "Free text");
  sub->callback(
      [options, &context] { context.run = [options, &context] { RunCreate(*options, context); }; });
}

void AddList(CLI::App& map_app, CliContext& context) {
  CLI::App* sub =
      map_app.add_subcommand("list", "List the maps: name, trees, version, crs, extent");
  sub->callback([&context] {
    context.run = [&context] {
      *context.out << FormatMapTable(context.Connect().ListMaps()) << std::flush;
    };
  });
}

void AddShow(CLI::App& map_app, CliContext& context) {
  auto name = std::make_shared<std::string>();
  CLI::App* sub = map_app.add_subcommand("show", "Show a map's fields");
  sub->add_option("NAME", *name, "Map name")->required();
  sub->callback([name, &context] {
    context.run = [name, &context] {
      *context.out << FormatMapDetails(context.Connect().GetMap(*name)) << std::flush;
    };
  });
}

void AddDelete(CLI::App& map_app, CliContext& context) {
  auto name = std::make_shared<std::string>();
  CLI::App* sub = map_app.add_subcommand("delete", "Delete a map and all its trees");
  sub->add_option("NAME", *name, "Map name")->required();
  sub->callback([name, &context] {
    context.run = [name, &context] {
      context.Connect().DeleteMap(*name);
      *context.out << "deleted map '" << *name << "'" << std::endl;
    };
  });
}

struct ExportOptions {
  std::string name;
  std::string out_file;  // empty or "-": stdout
};

void RunExport(const ExportOptions& options, const CliContext& context) {
  const ExportedTrees exported = context.Connect().ExportTrees(options.name);
  if (options.out_file.empty() || options.out_file == "-") {
    WriteMapTreesCsv(*context.out, exported.trees);
    context.out->flush();
    if (!*context.out) throw CommandError("writing to standard output failed");
    return;
  }
  WriteMapTreesCsv(options.out_file, exported.trees);
  *context.err << "exported " << exported.trees.size() << " trees of map '" << options.name
               << "' (version " << exported.map_version << ") to " << options.out_file << std::endl;
}

void AddExport(CLI::App& map_app, CliContext& context) {
  auto options = std::make_shared<ExportOptions>();
  CLI::App* sub =
      map_app.add_subcommand("export", "Write a map's trees as CSV (id,x,y,z,dbh,<attributes>)");
  sub->add_option("NAME", options->name, "Map name")->required();
  sub->add_option("--out", options->out_file, "Output CSV file (default: standard output)");
  sub->callback(
      [options, &context] { context.run = [options, &context] { RunExport(*options, context); }; });
}

}  // namespace

void AddMapCommand(CLI::App& app, CliContext& context) {
  CLI::App* map_app = app.add_subcommand("map", "Create, list, show, delete and export maps");
  AddCreate(*map_app, context);
  AddList(*map_app, context);
  AddShow(*map_app, context);
  AddDelete(*map_app, context);
  AddExport(*map_app, context);
}

}  // namespace forestmap::client
