// forestmap-lab: the ForestMap lab, apart from `forestmap` so that the user's (and a drone's)
// command line carries no simulator and no scoring against ground truth. Relocalization and
// mapping benchmarks (bench-reloc, bench-mapping), load on a running forestmapd (bench-server,
// bench-load), the LiDAR scan simulator (simulate) and the demo's data (demo-data).
//
// Global flags and exit status as forestmap's (0 success, 1 the command failed, 2 an invalid
// command line); every failure is one line "forestmap-lab: error: ..." on stderr.

#include <CLI/CLI.hpp>

#include "client/lab/lab_commands.h"

int main(int argc, char** argv) {
  namespace client = forestmap::client;
  CLI::App app{
      "The ForestMap lab: benchmarks against ground truth and against forestmapd, the LiDAR "
      "scan simulator and demo data.",
      "forestmap-lab"};
  client::CliContext context;
  client::AddGlobalOptions(app, context);
  client::AddBenchRelocCommand(app, context);
  client::AddDemoDataCommand(app, context);
  client::AddBenchServerCommand(app, context);
  client::AddBenchLoadCommand(app, context);
  client::AddBenchMappingCommand(app, context);
  client::AddBenchChangesCommand(app, context);
  client::AddSimulateCommand(app, context);
  return client::RunCommandLine(app, context, argc, argv);
}
