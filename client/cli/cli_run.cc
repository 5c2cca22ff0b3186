// The global --server flag and the run of a command line, for forestmap and forestmap-lab.

#include <CLI/CLI.hpp>
#include <cstdlib>
#include <exception>
#include <iostream>
#include <string>

#include "client/cli/cli_context.h"

namespace forestmap::client {

void AddGlobalOptions(CLI::App& app, CliContext& context) {
  app.add_option("--server", context.server,
                 "forestmapd address HOST:PORT, or replicas HOST:PORT,HOST:PORT,... (reads and "
                 "relocalizations move to the next one when a replica is down); the environment "
                 "variable FORESTMAP_SERVER replaces the default")
      ->envname("FORESTMAP_SERVER")
      ->capture_default_str()
      ->check([](const std::string& address) {
        return address.empty() ? std::string("the address must not be empty") : std::string();
      });
  AddSecurityOptions(app, context);
}

int RunCommandLine(CLI::App& app, CliContext& context, int argc, char** argv) {
  const std::string program = app.get_name();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& error) {
    if (error.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) {
      return app.exit(error);  // --help
    }
    std::cerr << program << ": error: " << error.what() << "\n"
              << "Run with --help for more information." << std::endl;
    return 2;
  }
  if (!context.run) {  // only leaf subcommands set it: the program or `forestmap map` alone
    std::cerr << program << ": error: a command is required\n"
              << "Run with --help for more information." << std::endl;
    return 2;
  }
  try {
    context.run();
  } catch (const std::exception& error) {
    std::cerr << program << ": error: " << error.what() << std::endl;
    return 1;
  }
  return EXIT_SUCCESS;
}

}  // namespace forestmap::client
