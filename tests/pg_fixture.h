#pragma once
// A throwaway PostgreSQL for tests: a cluster made with `initdb` in a fresh temporary directory,
// served on a free 127.0.0.1 port (and a unix socket in that directory), stopped and removed at
// the end. When the process runs as root (CI), the cluster runs as the unprivileged user
// `nobody` (`runuser`), which owns the directory: PostgreSQL refuses to run as root.
//
// Under CTest one cluster serves every test of the run: the fixture test `pg_cluster_start`
// (the `pg_fixture start` command below) writes its URL to RunStateFile(the file named by the
// environment variable FORESTMAP_TEST_PG_STATE) and `pg_cluster_stop` removes it. A test binary
// run by hand starts its own cluster on first use and stops it at exit. FORESTMAP_TEST_PG_URL (a
// server URL, e.g. postgresql://user@host:5432) points the tests at an existing server instead.
//
// The binaries come from FORESTMAP_PG_BIN or /usr/lib/postgresql/15/bin (Debian's `postgresql`).

#include <memory>
#include <string>

namespace forestmap::testing {

class PostgresCluster {
 public:
  // initdb + pg_ctl start. Throws std::runtime_error with the log's tail on failure.
  static std::unique_ptr<PostgresCluster> Start();
  // Stops (immediate) and removes the directory, unless Detach() was called.
  ~PostgresCluster();
  PostgresCluster(const PostgresCluster&) = delete;
  PostgresCluster& operator=(const PostgresCluster&) = delete;

  // postgresql://postgres@127.0.0.1:PORT (append "/dbname").
  std::string server_url() const;
  const std::string& dir() const { return dir_; }
  // Stops the server (its clients' connections break; new ones are refused) and starts it
  // again on the same port, for tests of a database that goes away and comes back.
  void Stop();
  void Restart();
  // Leaves the cluster running when this object is destroyed (the CTest fixture's start).
  void Detach() { detached_ = true; }
  // Stops the cluster that lives in `dir` and removes the directory.
  static void StopAndRemove(const std::string& dir);

 private:
  PostgresCluster(std::string dir, int port) : dir_(std::move(dir)), port_(port) {}
  void StartServer();  // pg_ctl start on port_
  std::string dir_;
  int port_ = 0;
  bool detached_ = false;
};

// A TCP port on 127.0.0.1 that nothing listened on a moment ago.
int FreeLoopbackPort();

// The server URL the tests of this process use (see above); starts a cluster on first use.
std::string TestServerUrl();

// `state`.<pid of the parent process>: CTest starts the fixture and the tests as its children, so
// every CTest run has its own state file, and its own cluster, even beside another run in the
// same build folder.
std::string RunStateFile(const std::string& state);

// A fresh, empty database on the test server, dropped (connections forced out) on destruction.
class TestDatabase {
 public:
  TestDatabase();
  ~TestDatabase();
  TestDatabase(const TestDatabase&) = delete;
  TestDatabase& operator=(const TestDatabase&) = delete;
  const std::string& url() const { return url_; }

 private:
  std::string name_;
  std::string url_;
};

}  // namespace forestmap::testing
