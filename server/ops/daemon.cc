#include "server/ops/daemon.h"

#include <charconv>
#include <chrono>
#include <ctime>
#include <iomanip>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <system_error>
#include <utility>

#include "server/ops/logging.h"
#include "server/ops/tls.h"
#include "storage/backup.h"
#include "storage/open_store.h"
#include "storage/token_store.h"

namespace forestmap::server {
namespace {

// The help of a subcommand's --db, which defaults to forestmapd's own --db (its variable, the
// configuration file): the server's database.
constexpr const char* kDbHelp =
    "database of the server: SQLite file or postgresql:// URI (default: as forestmapd would "
    "serve it: --db, FORESTMAPD_DB, the configuration file's db, ./forestmap.db)";

struct TokenArgs {
  std::string db;  // empty: the server's
  std::string map = "*";
  std::string role = "read";
  std::string note;
  std::string expires_in;  // "" (never), or a duration: 90d, 12h, 30m, 3600s
  int64_t id = 0;
  bool json = false;  // token list: one JSON object per line instead of the table
};

// Milliseconds in a duration "<count><unit>" (unit s, m, h or d; 1 s to 100 years).
int64_t DurationMs(const std::string& text) {
  static constexpr std::pair<char, int64_t> kUnits[] = {
      {'s', 1000}, {'m', 60'000}, {'h', 3'600'000}, {'d', 86'400'000}};
  const std::invalid_argument bad(
      "--expires-in must be a count and a unit (s, m, h or d), "
      "e.g. 90d or 12h, between 1 s and 100 years; got '" +
      text + "'");
  if (text.size() < 2 || text.size() > 12) throw bad;
  int64_t count = 0;
  const char* end = text.data() + text.size() - 1;
  const auto [rest, error] = std::from_chars(text.data(), end, count);
  if (error != std::errc() || rest != end || count <= 0) throw bad;
  for (const auto& [unit, ms] : kUnits) {
    if (*end != unit) continue;
    if (count > 100LL * 366 * 86'400'000 / ms) throw bad;
    return count * ms;
  }
  throw bad;
}

std::string UtcTime(int64_t unix_ms) {
  const std::time_t seconds = static_cast<std::time_t>(unix_ms / 1000);
  std::tm utc{};
  gmtime_r(&seconds, &utc);
  std::ostringstream text;
  text << std::put_time(&utc, "%Y-%m-%dT%H:%M:%SZ");
  return text.str();
}

int CreateToken(const TokenArgs& args, std::ostream& out) {
  const std::optional<storage::Role> role = storage::ParseRole(args.role);
  if (!role) throw std::invalid_argument("--role must be read, write or admin");
  const int64_t lifetime_ms = args.expires_in.empty() ? 0 : DurationMs(args.expires_in);
  storage::TokenStore tokens(args.db);
  const int64_t expires = lifetime_ms == 0
                              ? 0
                              : std::chrono::duration_cast<std::chrono::milliseconds>(
                                    std::chrono::system_clock::now().time_since_epoch())
                                        .count() +
                                    lifetime_ms;
  const storage::NewToken token = tokens.Create(args.map, *role, args.note, expires);
  out << token.secret << "\n";
  std::cerr << "token " << token.record.id << ": role " << storage::RoleName(*role) << " on maps '"
            << args.map << "'"
            << (expires != 0 ? ", valid until " + UtcTime(expires) : std::string())
            << ". The secret above is shown only this once; "
            << "clients pass it with --token or FORESTMAP_TOKEN.\n";
  return 0;
}

// A token as one JSON object (as `forestmap map list --json` prints maps): times in Unix ms, null
// for never.
nlohmann::ordered_json TokenJson(const storage::TokenRecord& token) {
  const auto time_or_null = [](int64_t unix_ms) {
    return unix_ms != 0 ? nlohmann::ordered_json(unix_ms) : nlohmann::ordered_json(nullptr);
  };
  nlohmann::ordered_json json;
  json["id"] = token.id;
  json["role"] = storage::RoleName(token.role);
  json["maps"] = token.map_pattern;
  json["created_unix_ms"] = token.created_unix_ms;
  json["revoked_unix_ms"] = time_or_null(token.revoked_unix_ms);
  json["expires_unix_ms"] = time_or_null(token.expires_unix_ms);
  json["note"] = token.note;
  return json;
}

int ListTokens(const TokenArgs& args, std::ostream& out) {
  storage::TokenStore tokens(args.db);
  if (args.json) {
    for (const storage::TokenRecord& token : tokens.List()) out << TokenJson(token).dump() << "\n";
    return 0;
  }
  out << "id\trole\tmaps\tcreated\trevoked\texpires\tnote\n";
  for (const storage::TokenRecord& token : tokens.List()) {
    out << token.id << "\t" << storage::RoleName(token.role) << "\t" << token.map_pattern << "\t"
        << UtcTime(token.created_unix_ms) << "\t"
        << (token.revoked() ? UtcTime(token.revoked_unix_ms) : "-") << "\t"
        << (token.expires_unix_ms != 0 ? UtcTime(token.expires_unix_ms) : "-") << "\t" << token.note
        << "\n";
  }
  return 0;
}

int RevokeToken(const TokenArgs& args, std::ostream& out) {
  storage::TokenStore tokens(args.db);
  if (!tokens.Revoke(args.id)) {
    throw std::runtime_error("no valid token with id " + std::to_string(args.id) +
                             " (see forestmapd token list)");
  }
  out << "revoked token " << args.id << "\n";
  return 0;
}

}  // namespace

void AddTokenCommands(CLI::App& app, const std::string& server_db, std::function<int()>& run,
                      std::ostream& out) {
  CLI::App* token = app.add_subcommand("token", "manage access tokens (stored hashed in --db)");
  token->require_subcommand(1);
  auto args = std::make_shared<TokenArgs>();
  CLI::App* create = token->add_subcommand("create", "create a token; prints its secret once");
  CLI::App* list = token->add_subcommand("list", "list tokens (never their secrets)");
  CLI::App* revoke = token->add_subcommand("revoke", "revoke a token by id");
  for (CLI::App* command : {create, list, revoke}) command->add_option("--db", args->db, kDbHelp);
  create->add_option("--map", args->map, "map name, glob ('plot-*') or '*' for every map")
      ->capture_default_str();
  create->add_option("--role", args->role, "read, write or admin")
      ->check(CLI::IsMember({"read", "write", "admin"}))
      ->capture_default_str();
  create->add_option("--note", args->note, "who or what the token is for");
  create->add_option("--expires-in", args->expires_in,
                     "the token stops working after this long: 90d, 12h, 30m, 3600s "
                     "(default: never)");
  list->add_flag("--json", args->json,
                 "one JSON object per token and line (id, role, maps, created_unix_ms, "
                 "revoked_unix_ms, expires_unix_ms, note) instead of the table");
  revoke->add_option("id", args->id, "token id (see token list)")->required();
  // The server's --db is read when the command runs: after parsing, with every source applied.
  const auto command = [&run, &out, &server_db,
                        args](int (*action)(const TokenArgs&, std::ostream&)) {
    return [&run, &out, &server_db, args, action] {
      run = [&out, &server_db, args, action] {
        TokenArgs resolved = *args;
        if (resolved.db.empty()) resolved.db = server_db;
        return action(resolved, out);
      };
    };
  };
  create->callback(command(&CreateToken));
  list->callback(command(&ListTokens));
  revoke->callback(command(&RevokeToken));
}

void AddBackupCommand(CLI::App& app, const std::string& server_db, std::function<int()>& run,
                      std::ostream& out) {
  CLI::App* backup = app.add_subcommand(
      "backup", "copy the database consistently while the server keeps running (SQLite backup)");
  auto db = std::make_shared<std::string>();
  auto file = std::make_shared<std::string>();
  backup->add_option("--db", *db, kDbHelp);
  backup->add_option("--out", *file, "the copy to write (must not exist)")->required();
  backup->callback([&run, &out, &server_db, db, file] {
    if (db->empty()) *db = server_db;
    if (storage::IsPostgresUri(*db)) {
      throw CLI::ValidationError(
          "--db", "forestmapd backup copies a SQLite database; back up PostgreSQL (" +
                      storage::DescribeDatabase(*db) +
                      ") with its own tools: pg_dump --format=custom --file=forestmap.dump "
                      "'postgresql://...' (restore with pg_restore)");
    }
    run = [&out, db, file] {
      const storage::BackupResult result = storage::BackupDatabase(*db, *file);
      out << "backup " << *file << ": " << result.pages << " pages, " << result.bytes
          << " bytes, quick_check " << result.integrity << "\n";
      return 0;
    };
  });
}

bool WarnIfExposed(const std::string& listen_address, bool tls, bool tokens, Listener listener) {
  const bool web = listener == Listener::kWebPage, metrics = listener == Listener::kMetrics;
  if (metrics) tokens = true;  // nothing on it takes tokens
  if (IsLoopback(listen_address) || (tls && tokens)) return false;
  std::string missing;
  if (!tls) {
    missing = web ? "WITHOUT TLS (the web page is plain HTTP: tokens and maps cross the network "
                    "in clear; --tls-cert/--tls-key serve it over HTTPS)"
              : metrics
                  ? "WITHOUT TLS (the metrics port is plain HTTP: anyone who reaches it reads "
                    "the metrics and the readiness; keep it on a monitoring network, or "
                    "--metrics-tls)"
                  : "WITHOUT TLS (tokens and maps cross the network in clear; "
                    "--tls-cert/--tls-key)";
  }
  if (!tokens) {
    if (!missing.empty()) missing += " and ";
    missing += web ? "WITHOUT TOKENS (anyone who reaches the port can read every map; "
                     "forestmapd token create)"
                   : "WITHOUT TOKENS (anyone who reaches the port can read, change and delete "
                     "every map; forestmapd token create)";
  }
  // Error level: shown whatever --log-level says.
  Log(LogLevel::kError,
      std::string("WARNING: ") +
          (web       ? "web page "
           : metrics ? "metrics port "
                     : "") +
          "listening beyond loopback " + missing,
      {{"listen", listen_address}});
  return true;
}

void AnnounceHttpListener(const std::string& address, const std::string& url, bool tokens,
                          Listener listener) {
  const bool metrics = listener == Listener::kMetrics;
  Log(LogLevel::kInfo,
      (metrics ? "metrics on " : "web page on ") + url + (metrics ? "/metrics" : "/"));
  WarnIfExposed(address, url.starts_with("https://"), tokens, listener);
}

}  // namespace forestmap::server
