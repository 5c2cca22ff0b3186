#pragma once
// The subcommands of `forestmap-lab`: benchmarks against ground truth and against a running
// forestmapd, the LiDAR scan simulator and the demo's data. Registered like forestmap's
// (client/cli/cli_context.h), one cli_<name>.cc each, from client/lab/main.cc.

#include "client/cli/cli_context.h"

namespace forestmap::client {

void AddBenchRelocCommand(CLI::App& app, CliContext& context);    // cli_bench_reloc.cc
void AddDemoDataCommand(CLI::App& app, CliContext& context);      // cli_demo_data.cc
void AddBenchServerCommand(CLI::App& app, CliContext& context);   // cli_bench_server.cc
void AddBenchLoadCommand(CLI::App& app, CliContext& context);     // cli_bench_load.cc
void AddBenchMappingCommand(CLI::App& app, CliContext& context);  // cli_bench_mapping.cc
void AddSimulateCommand(CLI::App& app, CliContext& context);      // cli_simulate.cc
void AddBenchChangesCommand(CLI::App& app, CliContext& context);  // cli_bench_changes.cc

}  // namespace forestmap::client
