// forestmapd: the ForestMap gRPC server. Reads its configuration (command line, environment,
// configuration file: server/ops/config.h), opens the database, serves until SIGINT or SIGTERM,
// then shuts down cleanly (running calls get a grace period). SIGHUP reloads the log level and
// the TLS files.

#include <pthread.h>
#include <signal.h>

#include <CLI/CLI.hpp>
#include <atomic>
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
#include <vector>

#include "forestmap_version.h"
#include "server/app/readiness.h"
#include "server/grpc/server.h"
#include "server/grpc/service.h"
#include "server/grpc/status.h"
#include "server/http/http_listen.h"
#include "server/http/http_page.h"
#include "server/http/metrics_http.h"
#include "server/ops/auth.h"
#include "server/ops/config.h"
#include "server/ops/daemon.h"
#include "server/ops/logging.h"
#include "server/ops/metrics.h"
#include "server/ops/server_metrics.h"
#include "server/ops/tls.h"
#include "storage/open_store.h"
#include "storage/token_store.h"

namespace {

constexpr auto kShutdownGrace = std::chrono::seconds(5);

using forestmap::server::Log;
using forestmap::server::LogLevel;

// A start-up failure: one error line naming the flag at fault (field "flag"), exit status 1.
int StartupFailure(const std::string& message) {
  std::vector<forestmap::server::LogField> fields;
  const std::string flag = forestmap::server::FlagNamedIn(message);
  if (!flag.empty()) fields.push_back({"flag", flag});
  const std::string grpc = forestmap::server::HeldGrpcErrors();
  if (!grpc.empty()) fields.push_back({"grpc", grpc});
  fields.push_back({"exit_code", std::to_string(forestmap::server::kExitFailure), true});
  Log(LogLevel::kError, message, fields);
  return forestmap::server::kExitFailure;
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
  std::string metrics;       // host:port of the Prometheus endpoint; empty: none
  bool metrics_tls = false;  // --metrics-tls: the metrics port with the TLS of --tls-cert
  int64_t max_db_mb = 0;     // MiB the SQLite database may grow to; 0: no limit
  forestmap::server::StreamLimitOptions streams;  // --max-streams, --max-streams-per-client
  double stream_idle_timeout_s = 30;              // --stream-idle-timeout-s
  std::string preload;  // --preload all|NAME,...: indexes built at start and after writes
};

// Blocks SIGINT, SIGTERM and SIGHUP in this thread and in every thread started after it
// (gRPC's), so that they are only ever received by sigwait below: no async signal handler.
sigset_t BlockSignals() {
  sigset_t signals;
  sigemptyset(&signals);
  for (const int signal_number : {SIGINT, SIGTERM, SIGHUP}) sigaddset(&signals, signal_number);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  return signals;
}

// Runs `open`; when it throws, reports `failure: <what>` as a start-up failure, returns null.
template <typename T, typename Open>
std::unique_ptr<T> OpenOrLog(const std::string& failure, const Open& open) {
  try {
    return open();
  } catch (const std::exception& e) {
    StartupFailure(failure + ": " + e.what());
    return nullptr;
  }
}

// The gRPC server, its readiness, the web page and metrics port (destroyed in reverse order).
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
                         forestmap::storage::TokenStore& tokens,
                         const forestmap::server::TlsCredentials* tls) {
  forestmap::server::ServerOptions server_options;
  server_options.max_receive_message_bytes = config.max_message_mb << 20;
  server_options.metrics = &metrics;
  server_options.serving_at_start = false;  // until the readiness' first round says otherwise
  forestmap::server::HttpsSetup https;  // the web page's, and the metrics port's with --metrics-tls
  if (tls != nullptr) server_options.credentials = tls->credentials();
  if (tls != nullptr) https = [tls](SSL_CTX& ctx) { return tls->SetUpHttps(ctx); };
  if (config.metrics_tls && tls == nullptr) {
    throw std::runtime_error("--metrics-tls needs --tls-cert and --tls-key");
  }
  Listeners listeners;
  try {
    listeners.server =
        std::make_unique<forestmap::server::ServerRunner>(config.listen, service, server_options);
  } catch (const std::runtime_error& e) {
    throw std::runtime_error("--listen " + config.listen + ": " + e.what());
  }
  if (!config.http.empty()) {
    listeners.page = std::make_unique<forestmap::server::HttpPage>(store, service.recent_answers(),
                                                                   config.http, &tokens, https);
  }
  // Readiness last (it logs): a failing listener is the only line; /readyz says "starting".
  auto readiness = std::make_shared<std::atomic<const forestmap::server::Readiness*>>(nullptr);
  if (!config.metrics.empty()) {
    listeners.metrics_http = std::make_unique<forestmap::server::MetricsHttpServer>(
        config.metrics, [&metrics] { return metrics.Render(); },
        [readiness] {
          const forestmap::server::Readiness* started = *readiness;
          if (started == nullptr) return std::make_pair(false, std::string("starting"));
          const auto state = started->state();
          return std::make_pair(state.ready, state.reason);
        },
        config.metrics_tls ? https : forestmap::server::HttpsSetup());
  }
  listeners.readiness = StartReadiness(config, store, service, *listeners.server);
  *readiness = listeners.readiness.get();
  forestmap::server::AddReadinessMetric(metrics, *listeners.readiness);
  return listeners;
}

// The warnings and lines of the listeners, once all of them started.
void AnnounceListeners(const Config& config, const Listeners& listeners, bool tls, bool tokens) {
  using forestmap::server::Listener;
  forestmap::server::WarnIfExposed(config.listen, tls, tokens);
  if (listeners.page) {
    forestmap::server::AnnounceHttpListener(config.http, listeners.page->url(), tokens,
                                            Listener::kWebPage);
  }
  if (listeners.metrics_http) {
    forestmap::server::AnnounceHttpListener(config.metrics, listeners.metrics_http->url(), tokens,
                                            Listener::kMetrics);
  }
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
  app.add_flag("--metrics-tls", config.metrics_tls,
               "serve --metrics over HTTPS with the TLS of --tls-cert, --tls-key and "
               "--tls-client-ca (default: plain HTTP, for a loopback or monitoring network)");
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

// forestmapd's command line around `config`: the flags of serving, their variables and the
// configuration file, --version, and (with `offline`) the token and backup subcommands.
std::unique_ptr<CLI::App> MakeApp(Config& config, std::function<int()>* offline) {
  auto app = std::make_unique<CLI::App>(
      "forestmapd: the ForestMap gRPC server (maps of trees, relocalization).\n"
      "Usage: forestmapd [--db PATH|postgresql://USER@HOST:PORT/DB] [--listen ADDR] "
      "[--max-message-mb N]\n"
      "                  [--http ADDR] [--keep-versions N] [--max-streams N] "
      "[--max-streams-per-client N]\n"
      "                  [--stream-idle-timeout-s S] [--tls-cert F --tls-key F [--tls-client-ca "
      "F]]\n"
      "                  [--metrics ADDR [--metrics-tls]] [--log-format text|json] "
      "[--log-level debug|info|warn|error] "
      "[--max-db-mb N] [--preload all|NAME,...]\n"
      "                  [--config FILE] [--version] [--help]\n"
      "       forestmapd token create [--db PATH] [--map NAME|GLOB|*] [--role read|write|admin] "
      "[--note TEXT] [--expires-in DURATION]\n"
      "       forestmapd token list [--db PATH] | token revoke [--db PATH] ID\n"
      "       forestmapd backup [--db PATH] --out FILE\n"
      "Every flag of serving is also the variable FORESTMAPD_<FLAG> (FORESTMAPD_LISTEN) and the "
      "key <flag> of the configuration file (listen = \"...\"); the command line wins over the "
      "environment, which wins over the file. Exit status: 0 ok, 1 failure, 2 usage error.",
      "forestmapd");
  AddServeOptions(*app, config);
  forestmap::server::AddConfigurationSources(*app, forestmap::VersionLine("forestmapd"));
  if (offline != nullptr) {
    forestmap::server::AddTokenCommands(*app, config.db, *offline, std::cout);
    forestmap::server::AddBackupCommand(*app, config.db, *offline, std::cout);
    app->require_subcommand(0, 1);
  }
  return app;
}

// What SIGHUP changes. The command line, the environment (as at start) and the configuration
// file (as now) are read again; the log level and the TLS files take effect (the next
// connections get the new certificate); other settings that changed need a restart. Tokens are
// looked up in the database at every call: nothing of theirs is cached. One log line says what
// was reloaded, and what was not.
class Reloader {
 public:
  Reloader(int argc, const char* const* argv, const CLI::App& started,
           forestmap::server::TlsCredentials* tls)
      : argc_(argc), argv_(argv), started_(started), tls_(tls) {}

  void Reload() const {
    Config config;
    const auto app = MakeApp(config, nullptr);
    try {
      app->parse(argc_, argv_);
    } catch (const CLI::ParseError& e) {
      Log(LogLevel::kError, std::string("SIGHUP: configuration not reloaded: ") + e.what());
      return;
    }
    std::vector<std::string> done, failed;
    const LogLevel level = forestmap::server::ParseLogLevel(config.log_level);
    done.push_back(std::string("log level ") + forestmap::server::LogLevelName(level) + " (was " +
                   forestmap::server::LogLevelName(forestmap::server::SetLogLevel(level)) + ")");
    if (tls_ != nullptr) {
      try {
        done.push_back("TLS certificate " + tls_->Reload(config.tls));
      } catch (const std::exception& e) {
        failed.push_back(std::string("TLS (kept ") + tls_->Describe() + "): " + e.what());
      }
    }
    std::vector<std::string> restart = forestmap::server::ChangedFlags(
        started_, *app, {"--log-level", "--tls-cert", "--tls-key", "--tls-client-ca"});
    if (tls_ == nullptr && config.tls.any()) restart.push_back("TLS on (--tls-cert)");
    std::string line = "SIGHUP: reloaded " + Join(done);
    if (!failed.empty()) line += "; NOT reloaded: " + Join(failed);
    if (!restart.empty()) line += "; changed, applied only by a restart: " + Join(restart);
    const std::string file = forestmap::server::ConfigFileRead(*app);
    Log(!failed.empty()    ? LogLevel::kError
        : !restart.empty() ? LogLevel::kWarn
                           : LogLevel::kInfo,
        line, {{"config", file.empty() ? "none" : file}});
  }

 private:
  static std::string Join(const std::vector<std::string>& parts) {
    std::string text;
    for (const std::string& part : parts) text += (text.empty() ? "" : ", ") + part;
    return text;
  }

  int argc_;
  const char* const* argv_;
  const CLI::App& started_;
  forestmap::server::TlsCredentials* tls_;
};

// Serves until SIGINT or SIGTERM; SIGHUP reloads.
void ServeUntilShutdown(const sigset_t& signals, const Reloader& reloader) {
  for (;;) {
    int signal_number = 0;
    sigwait(&signals, &signal_number);
    if (signal_number != SIGHUP) {
      forestmap::server::LogLine(std::string("received ") +
                                 (signal_number == SIGINT ? "SIGINT" : "SIGTERM") +
                                 ", shutting down");
      return;
    }
    try {
      reloader.Reload();
    } catch (const std::exception& e) {  // a reload never stops the server
      Log(LogLevel::kError, std::string("SIGHUP: reload failed: ") + e.what());
    }
  }
}

// Serves `config` (parsed by `app` from `argv`, read again on SIGHUP) until SIGINT or SIGTERM.
int Serve(const Config& config, const CLI::App& app, int argc, const char* const* argv) {
  using forestmap::server::LogLine;
  const sigset_t signals = BlockSignals();
  std::unique_ptr<forestmap::server::TlsCredentials> tls;
  if (config.tls.any()) {
    try {
      tls = std::make_unique<forestmap::server::TlsCredentials>(config.tls);
    } catch (const std::exception& e) {
      return StartupFailure(e.what());  // names --tls-cert, --tls-key or --tls-client-ca
    }
  }
  // A PostgreSQL URI may hold a password: only host, port and database are shown.
  const std::string shown_db = forestmap::storage::DescribeDatabase(config.db);
  const auto store = OpenOrLog<forestmap::storage::MapStore>(
      "--db: cannot open database " + shown_db,
      [&] { return forestmap::storage::OpenMapStore(config.db, config.max_db_mb); });
  if (!store) return forestmap::server::kExitFailure;
  if (const std::string warning = store->OpenWarning(); !warning.empty())
    Log(LogLevel::kWarn, warning);
  const size_t map_count = store->ListMaps().size();
  // Tokens live in the same database (table access_tokens), SQLite file or PostgreSQL.
  const auto tokens = OpenOrLog<forestmap::storage::TokenStore>(
      "--db: cannot open the access tokens of " + shown_db,
      [&] { return std::make_unique<forestmap::storage::TokenStore>(config.db); });
  if (!tokens) return forestmap::server::kExitFailure;
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
  forestmap::server::AddBuildInfo(metrics);
  Listeners listeners;
  try {
    listeners = StartListeners(config, *store, service, metrics, *tokens, tls.get());
  } catch (const std::exception& e) {
    return StartupFailure(e.what());
  }
  forestmap::server::GrpcErrorsAreWarnings();
  AnnounceListeners(config, listeners, tls != nullptr, tokens->AnyToken());
  const std::string file = forestmap::server::ConfigFileRead(app);
  Log(LogLevel::kInfo,
      "serving on " + listeners.server->address() + ", database " + shown_db + ", " +
          std::to_string(map_count) + " maps",
      {{"config", file.empty() ? "none" : file}});

  ServeUntilShutdown(signals, Reloader(argc, argv, app, tls.get()));
  listeners.page.reset();
  listeners.server->Shutdown(kShutdownGrace);
  listeners.server->Wait();
  LogLine("stopped");
  return forestmap::server::kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  forestmap::server::ApplyEnvironmentAliases();
  forestmap::server::RouteGrpcLogs();
  Config config;
  std::function<int()> offline;  // a subcommand instead of serving
  const auto app = MakeApp(config, &offline);
  const int status = forestmap::server::ParseConfiguration(*app, argc, argv);
  if (status >= 0) return status;
  forestmap::server::ConfigureLogging({forestmap::server::ParseLogFormat(config.log_format),
                                       forestmap::server::ParseLogLevel(config.log_level)});
  try {
    return offline ? offline() : Serve(config, *app, argc, argv);
  } catch (const std::exception& e) {
    if (offline) {
      std::cerr << "forestmapd: error: " << e.what() << std::endl;
      return forestmap::server::kExitFailure;
    }
    return StartupFailure(std::string("fatal: ") + e.what());
  }
}
