#pragma once
// The subcommands of `forestmap`. Each lives in its own cli_<name>.cc and is registered by an
// Add<Name>Command function; main.cc only creates the app, calls those and runs the chosen one.
// To add a subcommand (detect, simulate, bench-reloc, demo-data, ...): write cli_<name>.cc with
// `void Add<Name>Command(CLI::App& app, CliContext& context)`, declare it here, call it from
// main.cc and add the file to the forestmap target.

#include <CLI/CLI.hpp>
#include <functional>
#include <iostream>
#include <stdexcept>
#include <string>

#include "client/lib/forestmap_client.h"

namespace forestmap::client {

// Shared by every subcommand: global flags and the action chosen on the command line.
struct CliContext {
  std::string server = "127.0.0.1:50051";  // --server, or FORESTMAP_SERVER
  ClientOptions client;  // --tls, --tls-ca, --tls-cert, --tls-key, --token (FORESTMAP_TOKEN)
  // Set by the chosen subcommand's parse callback; main runs it after parsing succeeded.
  std::function<void()> run;
  std::ostream* out = &std::cout;  // results (tables, CSV, JSON lines)
  std::ostream* err = &std::cerr;  // progress, summaries, warnings

  ForestMapClient Connect() const { return ForestMapClient(server, client); }
};

// A command that could not do its job; main prints "forestmap: error: <what>" and exits 1.
// (CsvError, RpcError and other std::exceptions are reported the same way.)
class CommandError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

void AddMapCommand(CLI::App& app, CliContext& context);            // cli_map.cc
void AddMapPruneCommand(CLI::App& map_app, CliContext& context);   // cli_prune.cc ("map prune")
void AddMapUploadCommand(CLI::App& map_app, CliContext& context);  // cli_map_upload.cc
void AddRelocalizeCommand(CLI::App& app, CliContext& context);     // cli_relocalize.cc
void AddBenchRelocCommand(CLI::App& app, CliContext& context);     // cli_bench_reloc.cc
void AddDemoDataCommand(CLI::App& app, CliContext& context);       // cli_demo_data.cc
void AddBenchServerCommand(CLI::App& app, CliContext& context);    // cli_bench_server.cc
void AddBenchLoadCommand(CLI::App& app, CliContext& context);      // cli_bench_load.cc
void AddBenchMappingCommand(CLI::App& app, CliContext& context);   // cli_bench_mapping.cc
void AddObserveCommand(CLI::App& app, CliContext& context);        // cli_observe.cc
void AddDetectCommand(CLI::App& app, CliContext& context);         // cli_detect.cc
void AddSimulateCommand(CLI::App& app, CliContext& context);       // cli_simulate.cc
void AddTrackCommand(CLI::App& app, CliContext& context);          // cli_track.cc
void AddHealthCommand(CLI::App& app, CliContext& context);         // cli_health.cc
void AddCompareCommand(CLI::App& app, CliContext& context);        // cli_compare.cc
void AddPlotCommand(CLI::App& app, CliContext& context);           // cli_plot.cc
// Global flags --tls, --tls-ca, --tls-cert, --tls-key, --token (cli_security.cc).
void AddSecurityOptions(CLI::App& app, CliContext& context);

}  // namespace forestmap::client
