// forestmapd: the ForestMap gRPC server. Parses the command line, opens the database, serves
// until SIGINT or SIGTERM, then shuts down cleanly (running calls get a grace period).

#include <pthread.h>
#include <signal.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <exception>
#include <memory>
#include <string>

#include "server/http_page.h"
#include "server/server.h"
#include "server/service.h"
#include "server/status.h"
#include "storage/postgres.h"
#include "storage/postgres_map_store.h"

namespace {

constexpr auto kShutdownGrace = std::chrono::seconds(5);

struct Config {
  std::string db = "./forestmap.db";
  std::string listen = "127.0.0.1:50051";
  int max_message_mb = 64;
  std::string http;  // --http ADDR: the read-only web page; empty: none
  int64_t keep_versions = 0;  // versions of each map kept readable (0: all)
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

int Serve(const Config& config, const sigset_t& shutdown_signals) {
  using forestmap::server::LogLine;
  // A PostgreSQL URI may hold a password: only host, port and database are shown.
  const std::string shown_db =
      forestmap::storage::IsPostgresUri(config.db)
          ? "postgresql " + forestmap::storage::pg::DescribeServer(config.db)
          : config.db;
  std::unique_ptr<forestmap::storage::MapStore> store;
  try {
    store = forestmap::storage::OpenMapStore(config.db);
  } catch (const std::exception& e) {
    LogLine("cannot open database " + shown_db + ": " + e.what());
    return 1;
  }
  const size_t map_count = store->ListMaps().size();

  forestmap::server::ServiceOptions service_options;
  service_options.keep_versions = config.keep_versions;
  forestmap::server::ForestMapService service(*store, service_options);
  forestmap::server::ServerOptions server_options;
  server_options.max_receive_message_bytes = config.max_message_mb << 20;
  std::unique_ptr<forestmap::server::ServerRunner> server;
  try {
    server =
        std::make_unique<forestmap::server::ServerRunner>(config.listen, service, server_options);
  } catch (const std::exception& e) {
    LogLine(e.what());
    return 1;
  }
  LogLine("serving on " + server->address() + ", database " + shown_db + ", " +
          std::to_string(map_count) + " maps");
  std::unique_ptr<forestmap::server::HttpPage> page;
  if (!config.http.empty()) {
    try {
      page = std::make_unique<forestmap::server::HttpPage>(*store, service.recent_answers(),
                                                           config.http);
    } catch (const std::exception& e) {
      LogLine(e.what());
      return 1;
    }
    LogLine("web page on http://" + page->address() + "/");
  }

  int signal_number = 0;
  sigwait(&shutdown_signals, &signal_number);
  LogLine(std::string("received ") + (signal_number == SIGINT ? "SIGINT" : "SIGTERM") +
          ", shutting down");
  page.reset();
  server->Shutdown(kShutdownGrace);
  server->Wait();
  LogLine("stopped");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Config config;
  CLI::App app{"forestmapd: the ForestMap gRPC server (maps of trees, relocalization)"};
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
                 "on host:port");
  app.add_option("--keep-versions", config.keep_versions,
                 "history retention: after every write a map keeps its newest N versions "
                 "readable (0: all)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  const sigset_t shutdown_signals = BlockShutdownSignals();
  try {
    return Serve(config, shutdown_signals);
  } catch (const std::exception& e) {
    forestmap::server::LogLine(std::string("fatal: ") + e.what());
    return 1;
  }
}
