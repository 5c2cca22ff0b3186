// The built binaries as an operator would run them: `forestmapd token create`, forestmapd serving
// with tokens (and TLS, JSON logs, metrics), `forestmap --token / FORESTMAP_TOKEN / --tls-ca`,
// `forestmapd backup` while it serves, and the warning for a listener beyond loopback.

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <thread>

namespace forestmap {
namespace {

namespace fs = std::filesystem;
constexpr auto kStartTimeout = std::chrono::seconds(20);

struct Result {
  int exit_code = -1;
  std::string out;
  std::string err;
};

std::string ReadFile(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

class DaemonSecurityTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string name = "daemon_security_test_";
    name.append(std::to_string(getpid()));
    dir_ = fs::temp_directory_path() / name;
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    db_ = (dir_ / "maps.db").string();
  }
  void TearDown() override {
    Stop();
    fs::remove_all(dir_);
  }

  // Runs a shell command line, capturing stdout and stderr.
  Result Run(const std::string& command) {
    const fs::path out = dir_ / "stdout", err = dir_ / "stderr";
    const int status =
        std::system((command + " >'" + out.string() + "' 2>'" + err.string() + "'").c_str());
    return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, ReadFile(out), ReadFile(err)};
  }
  Result Client(const std::string& args, const std::string& env = "") {
    return Run("env -u FORESTMAP_TOKEN -u FORESTMAP_SERVER " + env +
               " '" FORESTMAP_CLI_PATH "' --server " + address_ + " " + args);
  }

  // Starts forestmapd with `flags` on port 0 and waits for its "serving on" line.
  void Serve(const std::string& flags) {
    log_ = dir_ / ("server" + std::to_string(++starts_) + ".log");  // never a stale one
    const std::string command = "'" FORESTMAPD_PATH "' --db '" + db_ + "' " + flags + " 2>'" +
                                log_.string() + "' & echo $! > '" + (dir_ / "pid").string() + "'";
    ASSERT_EQ(std::system(command.c_str()), 0);
    pid_ = std::stoi(ReadFile(dir_ / "pid"));
    const std::regex serving(R"(serving on [^ ]*:(\d+))");
    const auto deadline = std::chrono::steady_clock::now() + kStartTimeout;
    std::smatch match;
    std::string log;
    while (std::chrono::steady_clock::now() < deadline) {
      log = ReadFile(log_);
      if (std::regex_search(log, match, serving)) {
        address_ = "127.0.0.1:" + match[1].str();
        return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    FAIL() << "forestmapd did not start: " << log;
  }
  void Stop() {
    if (pid_ <= 0) return;
    kill(pid_, SIGTERM);
    for (int i = 0; i < 200 && kill(pid_, 0) == 0; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(25));
    }
    pid_ = -1;
  }

  std::string CreateToken(const std::string& map, const std::string& role) {
    const Result result = Run("'" FORESTMAPD_PATH "' token create --db '" + db_ + "' --map '" +
                              map + "' --role " + role);
    EXPECT_EQ(result.exit_code, 0) << result.err;
    EXPECT_NE(result.err.find("shown only this once"), std::string::npos) << result.err;
    std::string secret = result.out;
    while (!secret.empty() && secret.back() == '\n') secret.pop_back();
    return secret;
  }

  fs::path dir_;
  fs::path log_;
  std::string db_;
  std::string address_;
  int pid_ = -1;
  int starts_ = 0;
};

TEST_F(DaemonSecurityTest, TokensFromTheCommandLineGateTheCli) {
  const std::string admin = CreateToken("*", "admin");
  const std::string reader = CreateToken("plot-*", "read");
  ASSERT_TRUE(admin.starts_with("fmt_"));
  Serve("--listen 127.0.0.1:0 --log-format json");

  Result result = Client("map list");
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_NE(result.err.find("UNAUTHENTICATED"), std::string::npos) << result.err;
  result = Client("--token " + admin + " map create plot-1");
  EXPECT_EQ(result.exit_code, 0) << result.err;
  result = Client("map list", "FORESTMAP_TOKEN=" + reader);
  EXPECT_EQ(result.exit_code, 0) << result.err;
  EXPECT_NE(result.out.find("plot-1"), std::string::npos) << result.out;
  result = Client("map delete plot-1", "FORESTMAP_TOKEN=" + reader);
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_NE(result.err.find("PERMISSION_DENIED"), std::string::npos) << result.err;

  // Revoked from the command line while the server runs: refused at the next call.
  const Result listed = Run("'" FORESTMAPD_PATH "' token list --db '" + db_ + "'");
  EXPECT_EQ(listed.out.find(reader), std::string::npos) << "token list shows a secret";
  EXPECT_EQ(Run("'" FORESTMAPD_PATH "' token revoke --db '" + db_ + "' 2").exit_code, 0);
  result = Client("map list", "FORESTMAP_TOKEN=" + reader);
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_NE(result.err.find("unknown or revoked"), std::string::npos) << result.err;

  // Every line of the log is a JSON object; the RPC lines name the call and its code.
  Stop();
  std::istringstream lines(ReadFile(log_));
  std::string line;
  int rpc_lines = 0;
  while (std::getline(lines, line)) {
    const nlohmann::json entry = nlohmann::json::parse(line);
    if (entry.at("msg") == "rpc") ++rpc_lines;
  }
  EXPECT_EQ(rpc_lines, 5);
}

TEST_F(DaemonSecurityTest, TlsServerRefusesPlaintextClients) {
  const std::string key = (dir_ / "key.pem").string(), cert = (dir_ / "cert.pem").string();
  ASSERT_EQ(Run("openssl req -x509 -newkey rsa:2048 -nodes -days 1 -subj /CN=test -addext "
                "subjectAltName=IP:127.0.0.1 -keyout '" +
                key + "' -out '" + cert + "'")
                .exit_code,
            0);
  Serve("--listen 127.0.0.1:0 --tls-cert '" + cert + "' --tls-key '" + key + "'");
  EXPECT_EQ(Client("map list").exit_code, 1);
  const Result result = Client("--tls-ca '" + cert + "' map list");
  EXPECT_EQ(result.exit_code, 0) << result.err;
}

TEST_F(DaemonSecurityTest, BackupWhileServingAndExposedListenerWarning) {
  Serve("--listen 0.0.0.0:0");
  EXPECT_NE(ReadFile(log_).find("WARNING: listening beyond loopback WITHOUT TLS"),
            std::string::npos)
      << ReadFile(log_);
  ASSERT_EQ(Client("map create plot-1").exit_code, 0);
  const std::string copy = (dir_ / "copy.db").string();
  Result result = Run("'" FORESTMAPD_PATH "' backup --db '" + db_ + "' --out '" + copy + "'");
  EXPECT_EQ(result.exit_code, 0) << result.err;
  EXPECT_NE(result.out.find("quick_check ok"), std::string::npos) << result.out;
  result = Run("'" FORESTMAPD_PATH "' backup --db '" + db_ + "' --out '" + copy + "'");
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_NE(result.err.find("exists"), std::string::npos) << result.err;
  Stop();
  // The copy serves the map.
  db_ = copy;
  Serve("--listen 127.0.0.1:0");
  result = Client("map list");
  EXPECT_NE(result.out.find("plot-1"), std::string::npos) << result.out << result.err;
}

}  // namespace
}  // namespace forestmap
