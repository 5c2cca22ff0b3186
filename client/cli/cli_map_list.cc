// `forestmap map list|show|history` (a table, or with --json one JSON object per line) and
// `forestmap map delete` (asks on a terminal; --yes otherwise).

#include <unistd.h>

#include <iomanip>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "client/cli/cli_commands.h"
#include "client/cli/cli_format.h"

namespace forestmap::client {
namespace {

const char* KindName(v1::MapVersion::Kind kind) {
  switch (kind) {
    case v1::MapVersion::KIND_CREATE:
      return "create";
    case v1::MapVersion::KIND_UPLOAD:
      return "upload";
    case v1::MapVersion::KIND_REPLACE:
      return "replace";
    case v1::MapVersion::KIND_OBSERVE:
      return "observe";
    case v1::MapVersion::KIND_RESTORE:
      return "restore";
    case v1::MapVersion::KIND_REMOVE_SOURCE:
      return "remove-source";
    case v1::MapVersion::KIND_MIGRATED:
      return "migrated";
    default:
      return "?";
  }
}

nlohmann::ordered_json MapJson(const v1::Map& map) {
  nlohmann::ordered_json json;
  json["name"] = map.name();
  json["description"] = map.description();
  json["crs"] = map.crs();
  if (map.crs_epsg() != 0) json["epsg"] = map.crs_epsg();
  json["version"] = map.version();
  json["trees"] = map.tree_count();
  if (map.has_extent()) {
    const v1::Box2& box = map.extent();
    json["extent"] = {box.min_x(), box.min_y(), box.max_x(), box.max_y()};
  } else {
    json["extent"] = nullptr;
  }
  json["created_unix_ms"] = map.created_unix_ms();
  json["updated_unix_ms"] = map.updated_unix_ms();
  json["has_boundary"] = map.has_boundary();
  return json;
}

nlohmann::ordered_json VersionJson(const v1::MapVersion& v) {
  nlohmann::ordered_json json;
  json["version"] = v.version();
  json["created_unix_ms"] = v.created_unix_ms();
  json["kind"] = KindName(v.kind());
  json["source"] = v.source();
  if (v.kind() == v1::MapVersion::KIND_RESTORE) json["restored_from"] = v.restored_from();
  json["trees"] = v.tree_count();
  json["confirmed"] = v.confirmed_count();
  json["trees_added"] = v.trees_added();
  json["trees_updated"] = v.trees_updated();
  json["trees_removed"] = v.trees_removed();
  json["observations_added"] = v.observations_added();
  json["observations_removed"] = v.observations_removed();
  return json;
}

void PrintHistory(const std::vector<v1::MapVersion>& versions, std::ostream& out) {
  out << std::left << std::setw(8) << "VERSION" << std::setw(22) << "TIME" << std::setw(14)
      << "KIND" << std::setw(16) << "SOURCE" << std::right << std::setw(9) << "TREES"
      << std::setw(10) << "CONFIRMED" << std::setw(8) << "ADDED" << std::setw(8) << "UPDATED"
      << std::setw(8) << "REMOVED" << std::setw(9) << "OBS+" << std::setw(9) << "OBS-"
      << "\n";
  for (const v1::MapVersion& v : versions) {
    std::string source = v.source().empty() ? "-" : TerminalSafe(v.source());
    if (v.kind() == v1::MapVersion::KIND_RESTORE)
      source = "from v" + std::to_string(v.restored_from());
    out << std::left << std::setw(8) << v.version() << std::setw(22)
        << FormatUnixMs(v.created_unix_ms()) << std::setw(14) << KindName(v.kind()) << std::setw(16)
        << source << std::right << std::setw(9) << v.tree_count() << std::setw(10)
        << v.confirmed_count() << std::setw(8) << v.trees_added() << std::setw(8)
        << v.trees_updated() << std::setw(8) << v.trees_removed() << std::setw(9)
        << v.observations_added() << std::setw(9) << v.observations_removed() << "\n";
  }
  out << std::flush;
}

// One JSON object per line (JSON Lines), as every --json output of forestmap.
template <typename Item, typename ToJson>
void PrintJsonLines(const std::vector<Item>& items, const ToJson& to_json, std::ostream& out) {
  for (const Item& item : items) out << to_json(item).dump() << "\n";
  out << std::flush;
}

void AddList(CLI::App& map_app, CliContext& context) {
  auto json = std::make_shared<bool>(false);
  CLI::App* sub =
      map_app.add_subcommand("list", "List the maps: name, trees, version, crs, extent");
  sub->add_flag("--json", *json, "One JSON object per map and line instead of a table");
  sub->callback([json, &context] {
    context.run = [json, &context] {
      const std::vector<v1::Map> maps = context.Connect().ListMaps();
      if (*json) {
        PrintJsonLines(maps, MapJson, *context.out);
      } else {
        *context.out << FormatMapTable(maps) << std::flush;
      }
    };
  });
}

void AddShow(CLI::App& map_app, CliContext& context) {
  auto name = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  CLI::App* sub = map_app.add_subcommand("show", "Show a map's fields");
  sub->add_option("NAME", *name, "Map name")->required();
  sub->add_flag("--json", *json, "One JSON object instead of text");
  sub->callback([name, json, &context] {
    context.run = [name, json, &context] {
      const v1::Map map = context.Connect().GetMap(*name);
      *context.out << (*json ? MapJson(map).dump() + "\n" : FormatMapDetails(map)) << std::flush;
    };
  });
}

void AddHistory(CLI::App& map_app, CliContext& context) {
  auto name = std::make_shared<std::string>();
  auto limit = std::make_shared<int>(0);
  auto json = std::make_shared<bool>(false);
  CLI::App* sub = map_app.add_subcommand("history", "List a map's versions, oldest first");
  sub->add_option("NAME", *name, "Map name")->required();
  sub->add_option("--limit", *limit, "Only the newest N versions (default: all)")
      ->check(CLI::NonNegativeNumber);
  sub->add_flag("--json", *json, "One JSON object per version and line instead of a table");
  sub->callback([name, limit, json, &context] {
    context.run = [name, limit, json, &context] {
      const std::vector<v1::MapVersion> versions = context.Connect().ListVersions(*name, *limit);
      if (*json) {
        PrintJsonLines(versions, VersionJson, *context.out);
      } else {
        PrintHistory(versions, *context.out);
      }
    };
  });
}

// Deleting a map removes its whole history: on a terminal the user confirms it by typing the
// map's name; elsewhere (scripts) --yes says so, and without it nothing is deleted.
void ConfirmDelete(const v1::Map& map, const CliContext& context) {
  const std::string what = "map '" + TerminalSafe(map.name()) + "' (" +
                           std::to_string(map.tree_count()) + " trees, " +
                           std::to_string(map.version()) + " versions of history)";
  if (!isatty(STDIN_FILENO)) {
    throw CommandError("refusing to delete " + what + " without --yes (standard input is not a " +
                       "terminal to ask on)");
  }
  *context.err << "Delete " << what << " for good? Type the map's name to confirm: " << std::flush;
  std::string answer;
  std::getline(std::cin, answer);
  if (answer != map.name()) throw CommandError("not deleted: the name typed does not match");
}

void AddDelete(CLI::App& map_app, CliContext& context) {
  auto name = std::make_shared<std::string>();
  auto yes = std::make_shared<bool>(false);
  CLI::App* sub = map_app.add_subcommand(
      "delete",
      "Delete a map, all its trees and its whole history (asks on a terminal; --yes in scripts)");
  sub->add_option("NAME", *name, "Map name")->required();
  sub->add_flag("--yes,-y", *yes, "Do not ask: delete the map and its history");
  sub->callback([name, yes, &context] {
    context.run = [name, yes, &context] {
      ForestMapClient client = context.Connect();
      if (!*yes) ConfirmDelete(client.GetMap(*name), context);
      client.DeleteMap(*name);
      *context.out << "deleted map '" << TerminalSafe(*name) << "'" << std::endl;
    };
  });
}

}  // namespace

void AddMapListingCommands(CLI::App& map_app, CliContext& context) {
  AddList(map_app, context);
  AddShow(map_app, context);
  AddDelete(map_app, context);
  AddHistory(map_app, context);
}

}  // namespace forestmap::client
