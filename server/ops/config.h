#pragma once
// Where forestmapd's settings come from. Each one is taken from the first of
//   1. the command line          --listen 0.0.0.0:50051
//   2. the environment           FORESTMAPD_LISTEN=0.0.0.0:50051 (FORESTMAPD_ + the flag in
//                                UPPER_SNAKE; FORESTMAP_DB and FORESTMAP_LISTEN, the unit's
//                                older names, are read when the FORESTMAPD_ ones are unset)
//   3. the configuration file    listen = "0.0.0.0:50051" (the flag without its dashes, TOML)
//   4. the built-in default.
// The more specific and the more temporary a source is, the more it wins: a flag typed for one
// run overrides the deployment's environment (a unit's Environment=, a pod's env), which
// overrides the file shared by every instance of a host or image. The file is --config PATH
// (or FORESTMAPD_CONFIG), else /etc/forestmapd/forestmapd.conf when it exists; --config ''
// reads none. Every value, from whichever source, passes the flag's own checks; an unknown key
// in the file is an error. CLI11 reads all three (Option::envname, App::set_config); by itself
// it lets the file win over the environment, so the file's reader here drops the keys whose
// variable is set.
//
// Exit statuses: 0 success (also --help and --version), 1 a runtime
// failure (database, listener, TLS files), 2 a usage error (flags, variables, the file).

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

namespace forestmap::server {

inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;
inline constexpr int kExitUsage = 2;
inline constexpr const char* kDefaultConfigFile = "/etc/forestmapd/forestmapd.conf";

// "--max-message-mb" -> "FORESTMAPD_MAX_MESSAGE_MB".
std::string EnvName(const std::string& flag);

// Sets FORESTMAPD_DB and FORESTMAPD_LISTEN from FORESTMAP_DB and FORESTMAP_LISTEN where only
// the older name is set. Call once, first thing in main (it changes the environment).
void ApplyEnvironmentAliases();

// Call after adding the flags of serving to `app` (the top level; not its subcommands): gives
// each its variable (EnvName), adds --config and --version (printing `version`).
void AddConfigurationSources(CLI::App& app, const std::string& version);

// Parses the command line, the environment and the file with `app`. Returns -1 to go on, or the
// exit status: 0 after printing --help or --version, kExitUsage after reporting a usage error
// as one line on stderr (one JSON object under --log-format json) that names the flag and where
// its value came from.
int ParseConfiguration(CLI::App& app, int argc, const char* const* argv);

// The configuration file ParseConfiguration read; empty when none.
std::string ConfigFileRead(const CLI::App& app);

// The first flag ("--listen") named in an error message, for the log's "flag" field; with
// `app`, the first that is a flag of it. Empty when none.
std::string FlagNamedIn(const std::string& text, const CLI::App* app = nullptr);

// The flags of `after` whose value (as given, or the default) differs from that of `before`,
// both parsed from the same command line; `ignored` flags are left out (SIGHUP: what needs a
// restart).
std::vector<std::string> ChangedFlags(const CLI::App& before, const CLI::App& after,
                                      const std::vector<std::string>& ignored);

}  // namespace forestmap::server
