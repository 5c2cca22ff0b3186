#pragma once
// Pieces of forestmapd's main besides serving: the offline subcommands (token admin, backup)
// and the warning for an exposed, unprotected listener.

#include <CLI/CLI.hpp>
#include <functional>
#include <ostream>
#include <string>

namespace forestmap::server {

// `forestmapd token create|list|revoke --db PATH ...` and `forestmapd backup --db PATH --out F`.
// Each sets `run` to its action (returning the exit status) when chosen; the action prints
// results to `out` (a new token's secret, once) and throws on failure.
void AddTokenCommands(CLI::App& app, std::function<int()>& run, std::ostream& out);
void AddBackupCommand(CLI::App& app, std::function<int()>& run, std::ostream& out);

// Which listener WarnIfExposed looks at: the gRPC port, or the read-only web page (plain HTTP).
enum class Listener { kGrpc, kWebPage };

// Logs a warning, loud and at startup, for a listener beyond loopback without TLS or without
// tokens. Returns true when it warned.
bool WarnIfExposed(const std::string& listen_address, bool tls, bool tokens,
                   Listener listener = Listener::kGrpc);

}  // namespace forestmap::server
