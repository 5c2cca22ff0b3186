// forestmap: the command line client of forestmapd.
//
// Exit status: 0 on success (a not_found relocalization is a success), 1 when the command
// failed (bad file, unreachable server, an RPC error), 2 for an invalid command line. Every
// failure is one line "forestmap: error: ..." on stderr.

#include <CLI/CLI.hpp>
#include <cstdlib>
#include <exception>
#include <iostream>
#include <string>

#include "client/cli/cli_commands.h"

int main(int argc, char** argv) {
  using forestmap::client::CliContext;
  CLI::App app{
      "Client of forestmapd, the forest map server: manage tree maps and relocalize "
      "scans in them.",
      "forestmap"};
  CliContext context;
  app.add_option("--server", context.server,
                 "forestmapd address HOST:PORT, or replicas HOST:PORT,HOST:PORT,... (reads and "
                 "relocalizations move to the next one when a replica is down); the environment "
                 "variable FORESTMAP_SERVER replaces the default")
      ->envname("FORESTMAP_SERVER")
      ->capture_default_str()
      ->check([](const std::string& address) {
        return address.empty() ? std::string("the address must not be empty") : std::string();
      });
  forestmap::client::AddSecurityOptions(app, context);
  forestmap::client::AddMapCommand(app, context);
  forestmap::client::AddHealthCommand(app, context);
  forestmap::client::AddRelocalizeCommand(app, context);
  forestmap::client::AddBenchRelocCommand(app, context);
  forestmap::client::AddDemoDataCommand(app, context);
  forestmap::client::AddBenchServerCommand(app, context);
  forestmap::client::AddBenchLoadCommand(app, context);
  forestmap::client::AddBenchMappingCommand(app, context);
  forestmap::client::AddObserveCommand(app, context);
  forestmap::client::AddDetectCommand(app, context);
  forestmap::client::AddSimulateCommand(app, context);
  forestmap::client::AddTrackCommand(app, context);
  forestmap::client::AddCompareCommand(app, context);
  forestmap::client::AddPlotCommand(app, context);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& error) {
    if (error.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) {
      return app.exit(error);  // --help
    }
    std::cerr << "forestmap: error: " << error.what() << "\n"
              << "Run with --help for more information." << std::endl;
    return 2;
  }
  if (!context.run) {  // only leaf subcommands set it: `forestmap` or `forestmap map` alone
    std::cerr << "forestmap: error: a command is required\n"
              << "Run with --help for more information." << std::endl;
    return 2;
  }
  try {
    context.run();
  } catch (const std::exception& error) {
    std::cerr << "forestmap: error: " << error.what() << std::endl;
    return 1;
  }
  return EXIT_SUCCESS;
}
