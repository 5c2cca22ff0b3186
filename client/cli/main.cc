// forestmap: the command line client of forestmapd.
//
// Exit status: 0 on success (a not_found relocalization is a success), 1 when the command
// failed (bad file, unreachable server, an RPC error), 2 for an invalid command line. Every
// failure is one line "forestmap: error: ..." on stderr.

#include <CLI/CLI.hpp>

#include "client/cli/cli_commands.h"

int main(int argc, char** argv) {
  namespace client = forestmap::client;
  CLI::App app{
      "Client of forestmapd, the forest map server: manage tree maps and relocalize "
      "scans in them.",
      "forestmap"};
  client::CliContext context;
  client::AddGlobalOptions(app, context);
  client::AddMapCommand(app, context);
  client::AddHealthCommand(app, context);
  client::AddRelocalizeCommand(app, context);
  client::AddObserveCommand(app, context);
  client::AddDetectCommand(app, context);
  client::AddTrackCommand(app, context);
  client::AddCompareCommand(app, context);
  client::AddPlotCommand(app, context);
  return client::RunCommandLine(app, context, argc, argv);
}
