// `forestmap map changes NAME --since VERSION|DATE [--to VERSION|DATE]`: the trees removed, new,
// grown and moved between two versions of a map, from two exports compared by tree id
// (map_changes.h); a summary table, or JSON, and the changes as CSV, GeoJSON or GeoPackage.

#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "client/cli/cli_commands.h"
#include "client/cli/cli_format.h"
#include "client/cli/cli_tree_input.h"
#include "client/cli/map_changes.h"
#include "client/io/file_replace.h"
#include "client/io/geo_io.h"

namespace forestmap::client {
namespace {

struct ChangesOptions {
  std::string name;
  std::string since;
  std::string to;        // empty: the current version
  std::string out_file;  // empty: no file
  bool json = false;
  ChangeOptions compare;
};

// --out's format by its extension: CSV, GeoJSON or GeoPackage.
TreeFormat OutFormat(const std::string& path) {
  const std::string extension = LowerExtension(path);
  if (extension == ".csv") return TreeFormat::kCsv;
  if (extension == ".geojson" || extension == ".json") return TreeFormat::kGeoJson;
  if (extension == ".gpkg") return TreeFormat::kGeoPackage;
  throw CommandError("--out " + path + ": name it .csv, .geojson or .gpkg");
}

ExportedTrees ExportVersion(ForestMapClient& client, const std::string& name,
                            const v1::MapVersion& version, std::ostream& err) {
  ExportedTrees exported =
      client.ExportTrees(name, std::nullopt, version.version(),
                         ProgressTo(err, "exporting version " + std::to_string(version.version()),
                                    version.tree_count(), kExportChunk));
  return exported;
}

// The changes into `path`: a CSV; one GeoJSON layer with the `change` field; a GeoPackage layer
// per kind (removed, new, grown, moved; each replaced, empty ones too, so that no layer of an
// earlier run is left), in the map's CRS.
void WriteChanges(const std::string& path, TreeFormat format, const MapChanges& changes,
                  const std::string& crs, std::ostream& err) {
  if (format == TreeFormat::kCsv) {
    ReplaceFile(path, [&](const std::string& temporary) {
      std::ofstream out(temporary);
      WriteChangesCsv(out, changes.changes);
      out.close();
      if (!out) throw CommandError(path + ": cannot write the changes");
    });
    WriteCrsSidecar(path, crs);
    return;
  }
  std::vector<std::string> warnings;
  if (format == TreeFormat::kGeoJson) {
    warnings = WriteGeoTrees(path, format, ChangeRows(changes.changes), crs, "changes");
  } else {
    for (ChangeKind kind : kChangeKinds) {
      std::vector<TreeChange> of_kind;
      for (const TreeChange& change : changes.changes) {
        if (change.kind == kind) of_kind.push_back(change);
      }
      for (std::string& warning :
           WriteGeoTrees(path, format, ChangeRows(of_kind), crs, ChangeKindName(kind))) {
        warnings.push_back(std::move(warning));
      }
    }
  }
  for (const std::string& warning : warnings) {
    err << "forestmap: warning: " << warning << std::endl;
  }
}

void RunChanges(const ChangesOptions& options, const CliContext& context) {
  const TreeFormat format =
      options.out_file.empty() ? TreeFormat::kCsv : OutFormat(options.out_file);
  if (!options.out_file.empty()) CheckNoSidecarClash(options.out_file, format);
  ForestMapClient client = context.Connect();
  const v1::Map map = client.GetMap(options.name);
  const std::vector<v1::MapVersion> versions = client.ListVersions(options.name);
  ChangesHeader header;
  header.map = map.name();
  header.crs = map.crs();
  header.options = options.compare;
  header.from = ResolveVersion(options.since, versions, "--since", options.name);
  header.to = options.to.empty() ? versions.back()
                                 : ResolveVersion(options.to, versions, "--to", options.name);
  if (header.from.version() > header.to.version()) {
    throw CommandError("--since " + options.since + " (version " +
                       std::to_string(header.from.version()) + ") is newer than --to " +
                       (options.to.empty() ? "(the current version, " : options.to + " (") +
                       "version " + std::to_string(header.to.version()) + ")");
  }
  const ExportedTrees before = ExportVersion(client, options.name, header.from, *context.err);
  const ExportedTrees after = ExportVersion(client, options.name, header.to, *context.err);
  const MapChanges changes = CompareExports(before, after, options.compare);
  if (options.json) {
    *context.out << ChangesJson(header, changes).dump() << std::endl;
  } else {
    PrintChangesTable(header, changes, *context.out);
  }
  if (!options.out_file.empty()) {
    WriteChanges(options.out_file, format, changes, map.crs(), *context.err);
    *context.err << "wrote " << changes.changes.size() << " changes to " << options.out_file;
    if (format == TreeFormat::kGeoPackage) {
      *context.err << " (layers removed, new, grown, moved)";
    }
    *context.err << std::endl;
  }
}

}  // namespace

void AddMapChangesCommand(CLI::App& map_app, CliContext& context) {
  auto options = std::make_shared<ChangesOptions>();
  CLI::App* sub = map_app.add_subcommand(
      "changes",
      "What changed in a map between two versions: trees removed, new, grown (DBH) and moved, "
      "compared by tree id; a summary, and with --out every change as CSV, GeoJSON (one layer, "
      "field 'change') or GeoPackage (a layer per kind), in the map's CRS");
  sub->add_option("NAME", options->name, "Map name")->required();
  sub->add_option("--since", options->since,
                  "The older version: a version number (see 'map history'), or a date or time "
                  "(2026-12-01, 2026-12-01T10:30:00Z; UTC unless it says +HH:MM): the last "
                  "version made at or before it")
      ->required();
  sub->add_option("--to", options->to,
                  "The newer version, as --since (default: the current version)");
  sub->add_option("--out", options->out_file,
                  "Write every change to this file: .csv, .geojson or .gpkg");
  sub->add_flag("--json", options->json, "One JSON object with every change instead of the table");
  sub->add_option("--min-dbh-change", options->compare.min_dbh_change,
                  "A DBH change (m) grown trees exceed (default: 2 sigma of the difference, from "
                  "each tree's dbh_sigma, else 1 cm for a surveyed value)")
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--min-move", options->compare.min_move,
                  "A distance (m) moved trees exceed (default: the 95% distance, 2.448 sigma of "
                  "the difference, from each tree's position_sigma, else 5 cm for a surveyed "
                  "value)")
      ->check(CLI::NonNegativeNumber);
  sub->add_flag("--candidates", options->compare.candidates,
                "Compare candidate trees (seen by drones, not confirmed) too");
  sub->callback([options, &context] {
    context.run = [options, &context] { RunChanges(*options, context); };
  });
}

}  // namespace forestmap::client
