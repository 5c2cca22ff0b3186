#pragma once
// The subcommands of `forestmap-lab`: benchmarks against ground truth and against a running
// forestmapd, the LiDAR scan simulator and the demo's data. Registered like forestmap's
// (client/cli/cli_context.h), one cli_<name>.cc each, from client/lab/main.cc.

#include <cstddef>
#include <ostream>
#include <string>

#include "client/cli/cli_context.h"

namespace forestmap::client {

void AddBenchRelocCommand(CLI::App& app, CliContext& context);    // cli_bench_reloc.cc
void AddDemoDataCommand(CLI::App& app, CliContext& context);      // cli_demo_data.cc
void AddBenchServerCommand(CLI::App& app, CliContext& context);   // cli_bench_server.cc
void AddBenchLoadCommand(CLI::App& app, CliContext& context);     // cli_bench_load.cc
void AddBenchMappingCommand(CLI::App& app, CliContext& context);  // cli_bench_mapping.cc
void AddSimulateCommand(CLI::App& app, CliContext& context);      // cli_simulate.cc
void AddBenchChangesCommand(CLI::App& app, CliContext& context);  // cli_bench_changes.cc

// A long job's progress on `err`: "LABEL: DONE/TOTAL", rewritten in place every `every` items and
// at the end (then a newline).
inline void LabProgress(std::ostream& err, const std::string& label, size_t done, size_t total,
                        size_t every) {
  if (done % every == 0 || done == total) err << label << ": " << done << "/" << total << "\r";
  if (done == total) err << "\n";
}

}  // namespace forestmap::client
