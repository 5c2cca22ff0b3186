// The global --server flag and the run of a command line, for forestmap and forestmap-lab.

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdlib>
#include <exception>
#include <iostream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "client/cli/cli_context.h"
#include "forestmap_version.h"

namespace forestmap::client {
namespace {

constexpr const char* kDefaultPort = "50051";

// "host" -> "host:50051" (gRPC would dial 443); "host:port", "[v6]:port", "unix:..." and
// "scheme://..." targets stay as given.
std::string WithDefaultPort(const std::string& address) {
  if (address.rfind("unix:", 0) == 0 || address.find("://") != std::string::npos) return address;
  const size_t bracket = address.rfind(']');
  const size_t colon = address.rfind(':');
  const bool bare_v6 = bracket == std::string::npos && colon != address.find(':');
  const bool has_port =
      colon != std::string::npos && (bracket == std::string::npos || colon > bracket);
  return has_port || bare_v6 ? address : address + ":" + kDefaultPort;
}

// Edit distance with adjacent transpositions (optimal string alignment): "craete" is 1 from
// "create".
size_t EditDistance(const std::string& a, const std::string& b) {
  std::vector<std::vector<size_t>> d(a.size() + 1, std::vector<size_t>(b.size() + 1));
  for (size_t i = 0; i <= a.size(); ++i) d[i][0] = i;
  for (size_t j = 0; j <= b.size(); ++j) d[0][j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    for (size_t j = 1; j <= b.size(); ++j) {
      d[i][j] = std::min(
          {d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
      if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) {
        d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
      }
    }
  }
  return d[a.size()][b.size()];
}

// The command the user was in: the deepest subcommand parsed.
const CLI::App& DeepestCommand(const CLI::App& app) {
  const std::vector<CLI::App*> parsed = app.get_subcommands();
  return parsed.empty() ? app : DeepestCommand(*parsed.front());
}

// "did you mean ..." for the words of the command line nobody expected: the closest subcommand of
// the command they were in, or the closest of its flags (and the global ones); "" when none is
// close (a third of the word's letters, at least one).
std::string Suggestion(const CLI::App& app) {
  // Each candidate with the command it belongs to.
  std::vector<std::pair<std::string, const CLI::App*>> names;
  const CLI::App& command = DeepestCommand(app);
  for (const CLI::App* sub : command.get_subcommands(std::function<bool(const CLI::App*)>())) {
    names.emplace_back(sub->get_name(), &command);
  }
  for (const CLI::App* scope = &command; scope != nullptr; scope = scope->get_parent()) {
    for (const CLI::Option* option : scope->get_options()) {
      for (const std::string& name : option->get_lnames()) names.emplace_back("--" + name, scope);
    }
  }
  const std::pair<std::string, const CLI::App*>* best = nullptr;
  size_t best_distance = 0;
  for (const std::string& word : app.remaining(true)) {
    for (const auto& candidate : names) {
      const size_t distance = EditDistance(word, candidate.first);
      if (distance == 0 || distance > std::max<size_t>(1, word.size() / 3)) continue;
      if (best == nullptr || distance < best_distance) {
        best = &candidate;
        best_distance = distance;
      }
    }
  }
  if (best == nullptr) return "";
  std::string path;
  for (const CLI::App* scope = best->second; scope != nullptr; scope = scope->get_parent()) {
    path = scope->get_name() + " " + path;
  }
  return "did you mean '" + path + best->first + "'?";
}

}  // namespace

void AddGlobalOptions(CLI::App& app, CliContext& context) {
  app.add_option("--server", context.server,
                 "forestmapd address HOST:PORT, or replicas HOST:PORT,HOST:PORT,... (reads and "
                 "relocalizations move to the next one when a replica is down); the environment "
                 "variable FORESTMAP_SERVER replaces the default")
      ->envname("FORESTMAP_SERVER")
      ->capture_default_str()
      ->check([](const std::string& address) {
        return address.empty() ? std::string("the address must not be empty") : std::string();
      })
      ->transform([](std::string list) {  // a missing port is forestmapd's, not gRPC's 443
        std::stringstream parts(list);
        std::string out;
        for (std::string address; std::getline(parts, address, ',');) {
          out += (out.empty() ? "" : ",") + WithDefaultPort(address);
        }
        return out;
      });
  AddSecurityOptions(app, context);
  app.set_version_flag("--version", VersionLine(app.get_name()),
                       "Print the version, git commit and build type");
}

int RunCommandLine(CLI::App& app, CliContext& context, int argc, char** argv) {
  const std::string program = app.get_name();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& error) {
    if (error.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) {
      return app.exit(error);  // --help
    }
    if (dynamic_cast<const CLI::ExtrasError*>(&error) != nullptr) {
      // CLI11 lists the words backwards ("x craete"): in the order they were typed instead.
      std::string words;
      for (const std::string& word : app.remaining(true))
        words += (words.empty() ? "" : " ") + word;
      std::cerr << program << ": error: unexpected argument(s): " << words << "\n";
      const std::string suggestion = Suggestion(app);
      if (!suggestion.empty()) std::cerr << program << ": " << suggestion << "\n";
    } else {
      std::cerr << program << ": error: " << error.what() << "\n";
    }
    std::cerr << "Run with --help for more information." << std::endl;
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
