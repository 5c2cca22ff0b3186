#include "tests/pg_fixture.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <pwd.h>
#include <sys/socket.h>
#include <sys/types.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <string>

#include "storage/postgres/connection.h"

namespace forestmap::testing {
namespace {

constexpr const char* kUnprivilegedUser = "nobody";
constexpr int kStartAttempts = 3;  // a port found free may be taken before postgres binds it

std::string BinDir() {
  const char* env = std::getenv("FORESTMAP_PG_BIN");
  const std::string dir = env != nullptr ? env : "/usr/lib/postgresql/15/bin";
  if (!std::filesystem::exists(dir + "/initdb")) {
    throw std::runtime_error("PostgreSQL test cluster: no initdb in " + dir +
                             " (install Debian's `postgresql`: deploy/install-deps.sh, or set "
                             "FORESTMAP_PG_BIN)");
  }
  return dir;
}

std::string Tail(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  const std::string all = text.str();
  constexpr size_t kTailChars = 2000;
  return all.size() > kTailChars ? all.substr(all.size() - kTailChars) : all;
}

// Runs `command` in `dir`, as `nobody` when we are root; output appended to dir/fixture.log.
void Run(const std::string& dir, const std::string& command) {
  const std::string as_user =
      geteuid() == 0 ? std::string("runuser -u ") + kUnprivilegedUser + " -- " : "";
  const std::string line =
      "cd '" + dir + "' && " + as_user + command + " >> '" + dir + "/fixture.log' 2>&1 < /dev/null";
  if (std::system(line.c_str()) != 0) {
    throw std::runtime_error("PostgreSQL test cluster: `" + command + "` failed:\n" +
                             Tail(dir + "/fixture.log") + Tail(dir + "/postgres.log"));
  }
}

std::string Slurp(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  return line;
}

}  // namespace

int FreeLoopbackPort() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t length = sizeof address;
  if (fd < 0 || bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0 ||
      getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length) != 0) {
    if (fd >= 0) close(fd);
    throw std::runtime_error("PostgreSQL test cluster: no free loopback port");
  }
  close(fd);
  return ntohs(address.sin_port);
}

std::unique_ptr<PostgresCluster> PostgresCluster::Start() {
  const std::string bin = BinDir();
  std::string pattern = (std::filesystem::temp_directory_path() / "forestmap-pg-XXXXXX").string();
  if (mkdtemp(pattern.data()) == nullptr) {
    throw std::runtime_error("PostgreSQL test cluster: cannot make a directory in /tmp");
  }
  const std::string dir = pattern;
  if (geteuid() == 0) {
    const passwd* user = getpwnam(kUnprivilegedUser);
    if (user == nullptr || chown(dir.c_str(), user->pw_uid, user->pw_gid) != 0) {
      std::filesystem::remove_all(dir);
      throw std::runtime_error(std::string("PostgreSQL test cluster: cannot hand ") + dir +
                               " to user " + kUnprivilegedUser);
    }
  }
  std::unique_ptr<PostgresCluster> cluster(new PostgresCluster(dir, 0));
  Run(dir, bin + "/initdb -D '" + dir + "/data' -U postgres -A trust -E UTF8 --locale=C " +
               "--no-sync --no-instructions");
  for (int attempt = 1;; ++attempt) {
    cluster->port_ = FreeLoopbackPort();
    try {
      cluster->StartServer();
      break;
    } catch (const std::exception&) {
      if (attempt == kStartAttempts) throw;
    }
  }
  return cluster;
}

void PostgresCluster::StartServer() {
  // fsync off: a test cluster never outlives a crash, and it makes CREATE DATABASE fast.
  const std::string options = "-p " + std::to_string(port_) + " -k '" + dir_ +
                              "' -c listen_addresses=127.0.0.1 -c fsync=off "
                              "-c synchronous_commit=off -c full_page_writes=off "
                              "-c max_connections=300";
  Run(dir_, BinDir() + "/pg_ctl -D '" + dir_ + "/data' -l '" + dir_ +
                "/postgres.log' -w -t 60 -o \"" + options + "\" start");
}

void PostgresCluster::Stop() {
  Run(dir_, BinDir() + "/pg_ctl -D '" + dir_ + "/data' -m fast -w stop");
}

void PostgresCluster::Restart() { StartServer(); }

PostgresCluster::~PostgresCluster() {
  if (detached_) return;
  try {
    StopAndRemove(dir_);
  } catch (...) {  // a destructor must not throw; the directory is in /tmp
  }
}

void PostgresCluster::StopAndRemove(const std::string& dir) {
  if (std::filesystem::exists(dir + "/data/postmaster.pid")) {
    Run(dir, BinDir() + "/pg_ctl -D '" + dir + "/data' -m immediate -w stop");
  }
  std::filesystem::remove_all(dir);
}

std::string PostgresCluster::server_url() const {
  return "postgresql://postgres@127.0.0.1:" + std::to_string(port_);
}

std::string RunStateFile(const std::string& state) {
  return state + "." + std::to_string(getppid());
}

std::string TestServerUrl() {
  static std::mutex mutex;
  static std::unique_ptr<PostgresCluster> own;  // stopped by its destructor at exit
  static std::string url;
  std::lock_guard<std::mutex> lock(mutex);
  if (!url.empty()) return url;
  if (const char* env = std::getenv("FORESTMAP_TEST_PG_URL")) return url = env;
  if (const char* state = std::getenv("FORESTMAP_TEST_PG_STATE")) {
    const std::string shared = Slurp(RunStateFile(state));
    if (!shared.empty()) return url = shared;
  }
  own = PostgresCluster::Start();
  return url = own->server_url();
}

TestDatabase::TestDatabase() {
  static std::atomic<int> counter{0};
  const std::string server = TestServerUrl();
  name_ = "fm_test_" + std::to_string(getpid()) + "_" + std::to_string(counter++);
  storage::pg::Connection admin(server + "/postgres");
  // Identifiers cannot be bound; this one is made of digits and letters above.
  admin.ExecScript(("DROP DATABASE IF EXISTS " + name_ + " WITH (FORCE)").c_str());
  admin.ExecScript(("CREATE DATABASE " + name_ + " TEMPLATE template0").c_str());
  url_ = server + "/" + name_;
}

TestDatabase::~TestDatabase() {
  try {
    storage::pg::Connection admin(TestServerUrl() + "/postgres");
    admin.ExecScript(("DROP DATABASE IF EXISTS " + name_ + " WITH (FORCE)").c_str());
  } catch (...) {  // the cluster goes away at the end anyway
  }
}

}  // namespace forestmap::testing
