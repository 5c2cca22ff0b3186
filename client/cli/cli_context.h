#pragma once
// What `forestmap` (client/cli) and `forestmap-lab` (client/lab) share: the context every
// subcommand gets, the global flags and the run of a parsed command line. Each subcommand lives in
// its own cli_<name>.cc with `void Add<Name>Command(CLI::App& app, CliContext& context)`, declared
// in cli_commands.h (forestmap) or lab_commands.h (forestmap-lab); a main creates the app, calls
// AddGlobalOptions and those, and returns RunCommandLine.

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

// A command that could not do its job; RunCommandLine prints "<program>: error: <what>" and
// returns 1. (CsvError, RpcError and other std::exceptions are reported the same way.)
class CommandError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The global flags: --server (FORESTMAP_SERVER) and the security flags --tls, --tls-ca,
// --tls-cert, --tls-key, --token (cli_security.cc).
void AddGlobalOptions(CLI::App& app, CliContext& context);
void AddSecurityOptions(CLI::App& app, CliContext& context);

// Parses `argv` and runs the chosen subcommand. Returns the exit status: 0 on success (and for
// --help), 1 when the command failed (bad file, unreachable server, an RPC error), 2 for an
// invalid command line or no subcommand. Every failure is one line "<app name>: error: ..." on
// stderr. Nothing escapes as an exception.
int RunCommandLine(CLI::App& app, CliContext& context, int argc, char** argv);

}  // namespace forestmap::client
