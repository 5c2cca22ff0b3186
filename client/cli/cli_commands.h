#pragma once
// The subcommands of `forestmap`. Each lives in its own cli_<name>.cc and is registered by an
// Add<Name>Command function; main.cc only creates the app, calls those and runs the chosen one
// (cli_context.h). To add a subcommand: write cli_<name>.cc with
// `void Add<Name>Command(CLI::App& app, CliContext& context)`, declare it here, call it from
// main.cc and add the file to the forestmap target. Benchmarks, the simulator and demo data are
// forestmap-lab's (client/lab/lab_commands.h).

#include <functional>

#include "client/cli/cli_context.h"

namespace forestmap::client {

void AddMapCommand(CLI::App& app, CliContext& context);             // cli_map.cc
void AddMapPruneCommand(CLI::App& map_app, CliContext& context);    // cli_prune.cc ("map prune")
void AddMapUploadCommand(CLI::App& map_app, CliContext& context);   // cli_map_upload.cc
void AddMapChangesCommand(CLI::App& map_app, CliContext& context);  // cli_map_changes.cc
// cli_map_list.cc: "map list", "map show", "map history" (each with --json) and "map delete".
void AddMapListingCommands(CLI::App& map_app, CliContext& context);
void AddRelocalizeCommand(CLI::App& app, CliContext& context);  // cli_relocalize.cc
void AddObserveCommand(CLI::App& app, CliContext& context);     // cli_observe.cc
void AddDetectCommand(CLI::App& app, CliContext& context);      // cli_detect.cc
void AddTrackCommand(CLI::App& app, CliContext& context);       // cli_track.cc
void AddHealthCommand(CLI::App& app, CliContext& context);      // cli_health.cc
void AddCompareCommand(CLI::App& app, CliContext& context);     // cli_compare.cc
void AddPlotCommand(CLI::App& app, CliContext& context);        // cli_plot.cc

// cli_relocalize.cc: NAME, or instead --maps A,B,C / --maps-matching GLOB / --all-maps (one of
// them), into `maps` (relocalize, track). Returns the check to call in the command's callback.
std::function<void()> AddMapSelection(CLI::App& command, MapSelection& maps);

}  // namespace forestmap::client
