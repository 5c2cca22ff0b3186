// Faults of the database, with the built binaries as an operator runs them: forestmapd on a
// read-only database refuses to start and says why (it used to "serve" and fail every write as
// INTERNAL), and a full database (--max-db-mb, as a full disk) answers RESOURCE_EXHAUSTED
// "database full" while the maps already stored stay intact and the server keeps serving. A server
// on PostgreSQL takes tokens too (`forestmapd token create --db postgresql://...`): it used to
// stay open whatever tokens were made. Its health tells the truth: NOT_SERVING (and /readyz 503)
// while PostgreSQL is down, SERVING again when it is back, and a preloaded map's index is warm
// before the server says it is ready.

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <thread>

#include "daemon_process.h"
#include "tests/pg_fixture.h"
#include "tests/server/http_get.h"

namespace forestmap {
namespace {

namespace fs = std::filesystem;
using Result = test::CommandResult;
using test::ReadFile;

// A CSV of `count` trees with an attribute each (x,y,dbh,species).
void WriteTrees(const fs::path& path, int count) {
  std::ofstream out(path);
  out << "x,y,dbh,species\n";
  for (int i = 0; i < count; ++i) {
    out << (i % 1000) * 2.5 << "," << (i / 1000) * 2.5 << ",0.3,Picea abies " << i << "\n";
  }
}

class DaemonFaultsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("daemon_faults_test_" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    db_ = (dir_ / "maps.db").string();
  }
  void TearDown() override {
    Stop();
    fs::permissions(dir_, fs::perms::owner_all);
    fs::remove_all(dir_);
  }

  // Runs a shell command line, capturing stdout and stderr (kept outside dir_, which a test may
  // make read-only).
  Result Run(const std::string& command) {
    const fs::path out = fs::temp_directory_path() / ("daemon_faults_out_" + Pid());
    const fs::path err = fs::temp_directory_path() / ("daemon_faults_err_" + Pid());
    Result result = test::RunShell(command, out, err);
    fs::remove(out);
    fs::remove(err);
    return result;
  }
  static std::string Pid() { return std::to_string(getpid()); }
  Result Client(const std::string& args) {
    return Run(test::ClientCommand(daemon_.address(), args));
  }

  // Starts forestmapd with `flags` on port 0 and waits for its "serving on" line.
  void Serve(const std::string& flags) { Serve(db_, flags); }
  void Serve(const std::string& db, const std::string& flags) {
    log_ = dir_ / "server.log";
    ASSERT_TRUE(
        daemon_.Start("--db '" + db + "' --listen 127.0.0.1:0 " + flags, log_, dir_ / "pid"));
  }
  void Stop() { daemon_.Stop(); }

  fs::path dir_;
  fs::path log_;
  std::string db_;
  test::DaemonProcess daemon_;
};

TEST_F(DaemonFaultsTest, ReadOnlyDatabaseRefusesToStartAndSaysWhy) {
  // A ForestMap database with a map, closed cleanly.
  Serve("");
  ASSERT_EQ(Client("map create plot").exit_code, 0);
  Stop();
  fs::permissions(dir_, fs::perms::all);
  fs::permissions(db_, fs::perms::owner_read | fs::perms::group_read | fs::perms::others_read);
  // Root writes a file whatever its mode: then run the server as nobody, as a service user.
  const std::string as_user = geteuid() == 0 ? "setpriv --reuid=65534 --regid=65534 "
                                               "--clear-groups "
                                             : "";
  // `timeout`: a server that starts serving (the old behaviour) fails the test instead of hanging.
  const Result result = Run("timeout 20 " + as_user + "'" FORESTMAPD_PATH "' --db '" + db_ +
                            "' --listen 127.0.0.1:0");
  EXPECT_EQ(result.exit_code, 1) << result.err;
  EXPECT_NE(result.err.find("is read-only: the file is not writable by this user"),
            std::string::npos)
      << result.err;
  EXPECT_EQ(result.err.find("serving on"), std::string::npos) << result.err;
}

TEST_F(DaemonFaultsTest, FullDatabaseAnswersResourceExhaustedAndKeepsServing) {
  WriteTrees(dir_ / "small.csv", 100);
  WriteTrees(dir_ / "big.csv", 30000);
  Serve("--max-db-mb 1");
  Result result = Client("map create small --trees '" + (dir_ / "small.csv").string() + "'");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  result = Client("map create big --trees '" + (dir_ / "big.csv").string() + "'");
  EXPECT_NE(result.exit_code, 0);
  EXPECT_NE(result.err.find("RESOURCE_EXHAUSTED"), std::string::npos) << result.err;
  EXPECT_NE(result.err.find("database full"), std::string::npos) << result.err;
  // The server log names the real cause; the map stored before is intact and still served.
  const std::string log = ReadFile(log_);
  EXPECT_NE(log.find("database or disk is full"), std::string::npos) << log;
  result = Client("map show small");
  EXPECT_EQ(result.exit_code, 0) << result.err;
  EXPECT_NE(result.out.find("100"), std::string::npos) << result.out;
  EXPECT_LE(fs::file_size(db_), 1u << 20);
}

TEST_F(DaemonFaultsTest, SizeLimitIsRefusedForPostgresql) {
  const Result result = Run("timeout 20 '" FORESTMAPD_PATH
                            "' --db postgresql://nobody@127.0.0.1:1/none --max-db-mb 5");
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_NE(result.err.find("size limit applies to SQLite only"), std::string::npos) << result.err;
}

TEST_F(DaemonFaultsTest, TokensOnPostgresqlDenyByDefault) {
  testing::TestDatabase database;
  Serve(database.url(), "");
  ASSERT_EQ(Client("map create plot-1").exit_code, 0);  // open while no token exists
  const auto create_token = [&](const std::string& role) {
    const Result result = Run("'" FORESTMAPD_PATH "' token create --db '" + database.url() +
                              "' --map 'plot-*' --role " + role);
    EXPECT_EQ(result.exit_code, 0) << result.err;
    std::string secret = result.out;
    while (!secret.empty() && secret.back() == '\n') secret.pop_back();
    return secret;
  };
  const std::string reader = create_token("read");
  const std::string admin = create_token("admin");
  // The running server sees the new tokens on its next call: closed now.
  Result result = Client("map list");
  EXPECT_NE(result.exit_code, 0);
  EXPECT_NE(result.err.find("UNAUTHENTICATED"), std::string::npos) << result.err;
  result = Client("--token " + reader + " map show plot-1");
  EXPECT_EQ(result.exit_code, 0) << result.err;
  result = Client("--token " + reader + " map delete --yes plot-1");
  EXPECT_NE(result.err.find("PERMISSION_DENIED"), std::string::npos) << result.err;
  EXPECT_EQ(Client("--token " + admin + " map create plot-2").exit_code, 0);
  result = Client("--token " + admin + "0 map list");
  EXPECT_NE(result.err.find("UNAUTHENTICATED"), std::string::npos) << result.err;
  result = Run("'" FORESTMAPD_PATH "' token list --db '" + database.url() + "'");
  EXPECT_EQ(result.exit_code, 0) << result.err;
  EXPECT_NE(result.out.find("\tread\tplot-*\t"), std::string::npos) << result.out;
  EXPECT_EQ(result.out.find(reader), std::string::npos);  // never the secret
  EXPECT_EQ(Run("'" FORESTMAPD_PATH "' token revoke --db '" + database.url() + "' 1").exit_code, 0);
  result = Client("--token " + reader + " map show plot-1");
  EXPECT_NE(result.err.find("UNAUTHENTICATED"), std::string::npos) << result.err;
  Stop();
}

// Polls `condition` (a server reacting to its database) until true; false after 60 s.
bool Eventually(const std::function<bool()>& condition) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (!condition()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return true;
}

TEST_F(DaemonFaultsTest, HealthIsNotServingWhilePostgresqlIsDownAndPreloadedIndexesAreWarm) {
  // A cluster of its own: this test stops it.
  const auto cluster = testing::PostgresCluster::Start();
  const std::string db = cluster->server_url() + "/postgres";
  WriteTrees(dir_ / "plot.csv", 2000);
  const int metrics_port = testing::FreeLoopbackPort();
  const auto readyz = [&] { return test::HttpGet("127.0.0.1", metrics_port, "/readyz"); };
  Serve(db, "--preload plot,absent --metrics 127.0.0.1:" + std::to_string(metrics_port));
  ASSERT_EQ(Client("map create plot --trees '" + (dir_ / "plot.csv").string() + "'").exit_code, 0);
  // The preload builds the new map's index without a query: the map's own status says so.
  EXPECT_TRUE(Eventually([&] { return Client("health --map plot").exit_code == 0; }))
      << Client("health --map plot").out;
  EXPECT_TRUE(Eventually([&] { return Client("health").exit_code == 0; }));
  const Result absent = Client("health --map absent");
  EXPECT_EQ(absent.exit_code, 1);
  EXPECT_NE(absent.out.find("NOT_SERVING"), std::string::npos) << absent.out;
  EXPECT_EQ(Client("health --map never-named").out.find("SERVING"), std::string::npos);
  const test::HttpAnswer ready = readyz();
  EXPECT_EQ(ready.status, 200) << ready.body;
  EXPECT_EQ(test::HttpGet("127.0.0.1", metrics_port, "/healthz").status, 200);
  const std::string metrics = test::HttpGet("127.0.0.1", metrics_port, "/metrics").body;
  EXPECT_NE(metrics.find("forestmap_ready 1"), std::string::npos);
  EXPECT_NE(metrics.find("forestmap_index_bytes{map=\"plot\"}"), std::string::npos);

  cluster->Stop();
  EXPECT_TRUE(Eventually([&] { return Client("health").exit_code == 1; }));
  const Result down = Client("health");
  EXPECT_NE(down.out.find("NOT_SERVING"), std::string::npos) << down.out << down.err;
  EXPECT_EQ(Client("health --map plot").exit_code, 1);
  const test::HttpAnswer not_ready = readyz();
  EXPECT_EQ(not_ready.status, 503);
  EXPECT_NE(not_ready.body.find("database"), std::string::npos) << not_ready.body;
  EXPECT_EQ(test::HttpGet("127.0.0.1", metrics_port, "/healthz").status, 200);  // alive

  cluster->Restart();
  EXPECT_TRUE(Eventually([&] { return Client("health").exit_code == 0; }));
  EXPECT_EQ(readyz().status, 200);
  const std::string log = ReadFile(log_);
  EXPECT_NE(log.find("not ready: database unreachable"), std::string::npos) << log;
  EXPECT_NE(log.find("ready"), std::string::npos) << log;
  Stop();
}

}  // namespace
}  // namespace forestmap
