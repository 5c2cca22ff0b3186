// `forestmap map prune NAME --keep N`: drop the history before a map's newest N versions.

#include <algorithm>
#include <cstdint>
#include <memory>
#include <string>

#include "client/cli/cli_commands.h"

namespace forestmap::client {

void AddMapPruneCommand(CLI::App& map_app, CliContext& context) {
  auto name = std::make_shared<std::string>();
  auto keep = std::make_shared<int64_t>(1);
  CLI::App* sub = map_app.add_subcommand(
      "prune",
      "Drop the history before the newest versions of a map (they can no longer be "
      "read or restored; the current trees do not change)");
  sub->add_option("NAME", *name, "Map name")->required();
  sub->add_option("--keep", *keep, "Versions to keep, the current one included")
      ->required()
      ->check(CLI::Range(int64_t{1}, int64_t{1} << 62));
  sub->callback([name, keep, &context] {
    context.run = [name, keep, &context] {
      const v1::PruneVersionsResponse r = context.Connect().PruneVersions(*name, *keep);
      *context.out << "pruned map '" << *name << "': " << r.versions_removed()
                   << " versions removed (" << r.tree_rows_removed() << " tree rows, "
                   << r.observation_rows_removed() << " observation rows); versions "
                   << std::max<int64_t>(1, r.map().version() - *keep + 1) << " to "
                   << r.map().version() << " remain" << std::endl;
    };
  });
}

}  // namespace forestmap::client
