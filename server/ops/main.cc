// forestmapd: the ForestMap gRPC server. Parses the command line, opens the database, serves
// until SIGINT or SIGTERM, then shuts down cleanly (running calls get a grace period).

#include <pthread.h>
#include <signal.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <iostream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>

#include "server/app/readiness.h"
#include "server/grpc/server.h"
#include "server/grpc/service.h"
#include "server/grpc/status.h"
#include "server/http/http_listen.h"
#include "server/http/http_page.h"
#include "server/http/metrics_http.h"
#include "server/ops/auth.h"
#include "server/ops/daemon.h"
#include "server/ops/logging.h"
#include "server/ops/metrics.h"
#include "server/ops/server_metrics.h"
#include "server/ops/tls.h"
#include "storage/open_store.h"
#include "storage/token_store.h"

namespace {

constexpr auto kShutdownGrace = std::chrono::seconds(5);

void LogError(const std::string& message) {
  forestmap::server::Log(forestmap::server::LogLevel::kError, message);
}

struct Config {
  std::string db = "./forestmap.db";
  std::string listen = "127.0.0.1:50051";
  int max_message_mb = 64;
  std::string http;                 // --http ADDR: the read-only web page; empty: none
  int64_t keep_versions = 0;        // versions of each map kept readable (0: all)
  forestmap::server::TlsFiles tls;  // --tls-cert, --tls-key, --tls-client-ca
  std::string log_format = "text";
  std::string log_level = "info";
  std::string metrics;    // host:port of the Prometheus endpoint; empty: none
  int64_t max_db_mb = 0;  // MiB the SQLite database may grow to; 0: no limit
  forestmap::server::StreamLimitOptions streams;  // --max-streams, --max-streams-per-client
  double stream_idle_timeout_s = 30;              // --stream-idle-timeout-s
  std::string preload;  // --preload all|NAME,...: indexes built at start and after writes
};

// Blocks SIGINT and SIGTERM in this thread and in every thread started after it (gRPC's), so
// that they are only ever received by sigwait below: no async signal handler at all.
sigset_t BlockShutdownSignals() {
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  return signals;
}

// Where `db` is, as logged: a PostgreSQL URI may hold a password, so only host, port and
// database are shown.
std::string ShownDatabase(const std::string& db) {
  return forestmap::storage::DescribeDatabase(db);
}

// Runs `open`; when it throws, logs `failure: <what>` as an error and returns null.
template <typename T, typename Open>
std::unique_ptr<T> OpenOrLog(const std::string& failure, const Open& open) {
  try {
    return open();
  } catch (const std::exception& e) {
    LogError(failure + ": " + e.what());
    return nullptr;
  }
}

// The gRPC server, its readiness, the optional web page and Prometheus endpoint (destroyed in
// reverse order).
struct Listeners {
  std::unique_ptr<forestmap::server::ServerRunner> server;
  std::unique_ptr<forestmap::server::Readiness> readiness;
  std::unique_ptr<forestmap::server::HttpPage> page;
  std::unique_ptr<forestmap::server::MetricsHttpServer> metrics_http;
};

// The readiness of `server` (server/app/readiness.h): its health status follows the database
// and the preloaded indexes; every change of the whole server's status is logged.
std::unique_ptr<forestmap::server::Readiness> StartReadiness(
    const Config& config, forestmap::storage::MapStore& store,
    forestmap::server::ForestMapService& service, forestmap::server::ServerRunner& server) {
  forestmap::server::ReadinessOptions options;
  if (!config.preload.empty()) forestmap::server::ParsePreload(config.preload, options);
  auto last = std::make_shared<std::optional<bool>>();
  return std::make_unique<forestmap::server::Readiness>(
      store, service.index_cache(), options,
      [&server, last](const std::string& name, bool serving, const std::string& reason) {
        server.SetServing(name, serving);
        if (!name.empty() || *last == serving) return;
        if (last->has_value()) {  // the first status is Readiness' own "starting"
          forestmap::server::Log(
              serving ? forestmap::server::LogLevel::kInfo : forestmap::server::LogLevel::kWarn,
              serving ? "ready" : "not ready: " + reason);
        }
        *last = serving;
      });
}

// Starts the listeners of `config` for `service`; throws when one cannot start.
Listeners StartListeners(const Config& config, forestmap::storage::MapStore& store,
                         forestmap::server::ForestMapService& service,
                         forestmap::server::Metrics& metrics,
                         forestmap::storage::TokenStore& tokens) {
  forestmap::server::ServerOptions server_options;
  server_options.max_receive_message_bytes = config.max_message_mb << 20;
  server_options.metrics = &metrics;
  server_options.serving_at_start = false;  // until the readiness' first round says otherwise
  const bool tls =
      !config.tls.cert.empty() || !config.tls.key.empty() || !config.tls.client_ca.empty();
  if (tls) server_options.credentials = forestmap::server::TlsServerCredentials(config.tls);
  Listeners listeners;
  listeners.server =
      std::make_unique<forestmap::server::ServerRunner>(config.listen, service, server_options);
  forestmap::server::WarnIfExposed(config.listen, tls, tokens.AnyToken());
  listeners.readiness = StartReadiness(config, store, service, *listeners.server);
  forestmap::server::AddReadinessMetric(metrics, *listeners.readiness);
  if (!config.http.empty()) {
    listeners.page = std::make_unique<forestmap::server::HttpPage>(store, service.recent_answers(),
                                                                   config.http, &tokens);
    forestmap::server::LogLine("web page on http://" + listeners.page->address() + "/");
    forestmap::server::WarnIfExposed(config.http, /*tls=*/false, tokens.AnyToken(),
                                     forestmap::server::Listener::kWebPage);
  }
  if (!config.metrics.empty()) {
    const forestmap::server::Readiness* readiness = listeners.readiness.get();
    listeners.metrics_http = std::make_unique<forestmap::server::MetricsHttpServer>(
        config.metrics, [&metrics] { return metrics.Render(); },
        [readiness] {
          const auto state = readiness->state();
          return std::make_pair(state.ready, state.reason);
        });
    forestmap::server::LogLine(
        "metrics on http://" +
        forestmap::server::BoundHttpAddress(config.metrics, listeners.metrics_http->port()) +
        "/metrics");
  }
  return listeners;
}

// Blocks until SIGINT or SIGTERM arrives, and logs which.
void WaitForShutdownSignal(const sigset_t& shutdown_signals) {
  int signal_number = 0;
  sigwait(&shutdown_signals, &signal_number);
  forestmap::server::LogLine(std::string("received ") +
                             (signal_number == SIGINT ? "SIGINT" : "SIGTERM") + ", shutting down");
}

// The flags of serving (not of the token and backup subcommands), into `config`.
void AddServeOptions(CLI::App& app, Config& config) {
  app.add_option("--db", config.db,
                 "SQLite database file (created if missing), or a PostgreSQL server as "
                 "postgresql://user@host:port/dbname (several replicas may share one)")
      ->capture_default_str();
  app.add_option("--listen", config.listen, "address to listen on, host:port (port 0: any)")
      ->capture_default_str();
  app.add_option("--max-message-mb", config.max_message_mb, "largest request message accepted, MiB")
      ->check(CLI::Range(1, 2047))
      ->capture_default_str();
  app.add_option("--http", config.http,
                 "also serve a read-only web page (maps, versions, trees, last relocalizations) "
                 "on host:port (port 0: any)");
  app.add_option("--keep-versions", config.keep_versions,
                 "history retention: after every write a map keeps its newest N versions "
                 "readable (0: all)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--tls-cert", config.tls.cert,
                 "PEM certificate chain: serve TLS (with --tls-key)");
  app.add_option("--tls-key", config.tls.key, "PEM private key of --tls-cert");
  app.add_option("--tls-client-ca", config.tls.client_ca,
                 "PEM CA bundle: require client certificates signed by it");
  app.add_option("--log-format", config.log_format, "log lines as text or json")
      ->check(CLI::IsMember({"text", "json"}))
      ->capture_default_str();
  app.add_option("--log-level", config.log_level, "debug, info, warn or error")
      ->check(CLI::IsMember({"debug", "info", "warn", "error"}))
      ->capture_default_str();
  app.add_option("--max-db-mb", config.max_db_mb,
                 "largest size of the SQLite database file, MiB (0: no limit); writes beyond "
                 "it answer RESOURCE_EXHAUSTED 'database full', as on a full disk")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--metrics", config.metrics,
                 "serve Prometheus metrics on http://HOST:PORT/metrics (port 0: any)");
  app.add_option("--max-streams", config.streams.max_streams,
                 "open UploadTrees + ExportTrees streams in all; more are RESOURCE_EXHAUSTED")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-streams-per-client", config.streams.max_streams_per_client,
                 "open UploadTrees + ExportTrees streams per client: per token, or per "
                 "connection without tokens; at most half of --max-streams")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--stream-idle-timeout-s", config.stream_idle_timeout_s,
                 "an UploadTrees, ExportTrees or Track stream waiting this long for its client "
                 "is cancelled, seconds")
      ->check(CLI::Range(0.001, 86400.0))
      ->capture_default_str();
  app.add_option("--preload", config.preload,
                 "build the relocalization indexes of these maps at start and again after "
                 "every write: 'all' or NAME,NAME,...; the server reports ready (gRPC health, "
                 "/readyz) once they are built")
      ->check([](const std::string& text) {
        forestmap::server::ReadinessOptions options;
        try {
          forestmap::server::ParsePreload(text, options);
        } catch (const std::invalid_argument& e) {
          return std::string(e.what());
        }
        return std::string();
      });
}

int Serve(const Config& config, const sigset_t& shutdown_signals) {
  using forestmap::server::LogLine;
  const std::string shown_db = ShownDatabase(config.db);
  const auto store = OpenOrLog<forestmap::storage::MapStore>(
      "cannot open database " + shown_db,
      [&] { return forestmap::storage::OpenMapStore(config.db, config.max_db_mb); });
  if (!store) return 1;
  const size_t map_count = store->ListMaps().size();
  // Tokens live in the same database (table access_tokens), SQLite file or PostgreSQL.
  const auto tokens = OpenOrLog<forestmap::storage::TokenStore>(
      "cannot open the access tokens of " + shown_db,
      [&] { return std::make_unique<forestmap::storage::TokenStore>(config.db); });
  if (!tokens) return 1;
  const forestmap::server::Authorizer authorizer(tokens.get());

  forestmap::server::ServiceOptions service_options;
  service_options.keep_versions = config.keep_versions;
  service_options.streams = config.streams;
  service_options.streams.idle_timeout =
      std::chrono::milliseconds(std::llround(config.stream_idle_timeout_s * 1000));
  service_options.authorizer = &authorizer;
  forestmap::server::ForestMapService service(*store, service_options);
  forestmap::server::Metrics metrics;
  forestmap::server::AddServerMetrics(metrics, service.index_cache(), service.answer_counts(),
                                      config.db);
  forestmap::server::AddProcessMetrics(metrics);
  Listeners listeners;
  try {
    listeners = StartListeners(config, *store, service, metrics, *tokens);
  } catch (const std::exception& e) {
    LogError(e.what());
    return 1;
  }
  LogLine("serving on " + listeners.server->address() + ", database " + shown_db + ", " +
          std::to_string(map_count) + " maps");

  WaitForShutdownSignal(shutdown_signals);
  listeners.page.reset();
  listeners.server->Shutdown(kShutdownGrace);
  listeners.server->Wait();
  LogLine("stopped");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Config config;
  CLI::App app{
      "forestmapd: the ForestMap gRPC server (maps of trees, relocalization).\n"
      "Usage: forestmapd [--db PATH|postgresql://USER@HOST:PORT/DB] [--listen ADDR] "
      "[--max-message-mb N]\n"
      "                  [--http ADDR] [--keep-versions N] [--max-streams N] "
      "[--max-streams-per-client N]\n"
      "                  [--stream-idle-timeout-s S] [--tls-cert F --tls-key F [--tls-client-ca "
      "F]]\n"
      "                  [--metrics ADDR] [--log-format text|json] "
      "[--log-level debug|info|warn|error] "
      "[--max-db-mb N] [--preload all|NAME,...] [--help]\n"
      "       forestmapd token create --db PATH [--map NAME|GLOB|*] [--role read|write|admin] "
      "[--note TEXT] [--expires-in DURATION]\n"
      "       forestmapd token list --db PATH | token revoke --db PATH ID\n"
      "       forestmapd backup --db PATH --out FILE"};
  AddServeOptions(app, config);
  std::function<int()> offline;  // a subcommand instead of serving
  forestmap::server::AddTokenCommands(app, offline, std::cout);
  forestmap::server::AddBackupCommand(app, offline, std::cout);
  app.require_subcommand(0, 1);
  CLI11_PARSE(app, argc, argv);
  forestmap::server::ConfigureLogging({forestmap::server::ParseLogFormat(config.log_format),
                                       forestmap::server::ParseLogLevel(config.log_level)});
  if (offline) {
    try {
      return offline();
    } catch (const std::exception& e) {
      std::cerr << "forestmapd: error: " << e.what() << std::endl;
      return 1;
    }
  }

  const sigset_t shutdown_signals = BlockShutdownSignals();
  try {
    return Serve(config, shutdown_signals);
  } catch (const std::exception& e) {
    LogError(std::string("fatal: ") + e.what());
    return 1;
  }
}
