#pragma once
// Pieces of forestmapd's main besides serving: the offline subcommands (token admin, backup)
// and the warning for an exposed, unprotected listener.

#include <CLI/CLI.hpp>
#include <functional>
#include <ostream>
#include <string>

namespace forestmap::server {

// `forestmapd token create|list|revoke [--db PATH] ...` and `forestmapd backup [--db PATH] --out
// F`. Without their --db they use `server_db`, forestmapd's own --db as parsed (flag, variable,
// configuration file, default), read when the action runs. Each sets `run` to its action
// (returning the exit status) when chosen; the action prints results to `out` (a new token's
// secret, once) and throws on failure. A PostgreSQL --db for backup is a usage error (CLI11's
// ValidationError, at parsing) that names pg_dump.
void AddTokenCommands(CLI::App& app, const std::string& server_db, std::function<int()>& run,
                      std::ostream& out);
void AddBackupCommand(CLI::App& app, const std::string& server_db, std::function<int()>& run,
                      std::ostream& out);

// Which listener WarnIfExposed looks at: the gRPC port, the read-only web page, or the metrics
// port (which takes no tokens).
enum class Listener { kGrpc, kWebPage, kMetrics };

// Logs a warning, loud and at startup, for a listener beyond loopback without TLS or (but the
// metrics port) without tokens. Returns true when it warned.
bool WarnIfExposed(const std::string& listen_address, bool tls, bool tokens,
                   Listener listener = Listener::kGrpc);

// For the web page or the metrics port, configured as `address` and serving at `url`
// ("https://host:port"): the line saying where ("web page on https://host:port/"), and
// WarnIfExposed's warning.
void AnnounceHttpListener(const std::string& address, const std::string& url, bool tokens,
                          Listener listener);

}  // namespace forestmap::server
