// The built binaries as an operator would run them: `forestmapd token create`, forestmapd serving
// with tokens (and TLS, JSON logs, metrics), `forestmap --token / FORESTMAP_TOKEN / --tls-ca`,
// `forestmapd backup` while it serves, and the warning for a listener beyond loopback.

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>

#include "daemon_process.h"

namespace forestmap {
namespace {

namespace fs = std::filesystem;
using Result = test::CommandResult;
using test::ReadFile;

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
    return test::RunShell(command, dir_ / "stdout", dir_ / "stderr");
  }
  Result Client(const std::string& args, const std::string& env = "") {
    return Run(test::ClientCommand(daemon_.address(), args, env));
  }

  // Starts forestmapd with `flags` and waits for its "serving on" line.
  void Serve(const std::string& flags) {
    log_ = dir_ / ("server" + std::to_string(++starts_) + ".log");  // never a stale one
    ASSERT_TRUE(daemon_.Start("--db '" + db_ + "' " + flags, log_, dir_ / "pid"));
  }
  void Stop() { daemon_.Stop(); }

  std::string CreateToken(const std::string& map, const std::string& role,
                          const std::string& more = "") {
    const Result result = Run("'" FORESTMAPD_PATH "' token create --db '" + db_ + "' --map '" +
                              map + "' --role " + role + " " + more);
    EXPECT_EQ(result.exit_code, 0) << result.err;
    EXPECT_NE(result.err.find("shown only this once"), std::string::npos) << result.err;
    std::string secret = result.out;
    while (!secret.empty() && secret.back() == '\n') secret.pop_back();
    return secret;
  }

  fs::path dir_;
  fs::path log_;
  std::string db_;
  test::DaemonProcess daemon_;
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
  result = Client("map delete --yes plot-1", "FORESTMAP_TOKEN=" + reader);
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_NE(result.err.find("PERMISSION_DENIED"), std::string::npos) << result.err;

  // Revoked from the command line while the server runs: refused at the next call.
  const Result listed = Run("'" FORESTMAPD_PATH "' token list --db '" + db_ + "'");
  EXPECT_EQ(listed.out.find(reader), std::string::npos) << "token list shows a secret";
  EXPECT_EQ(Run("'" FORESTMAPD_PATH "' token revoke --db '" + db_ + "' 2").exit_code, 0);
  result = Client("map list", "FORESTMAP_TOKEN=" + reader);
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_NE(result.err.find("unknown, revoked or expired"), std::string::npos) << result.err;

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

// A token with a lifetime works until it ends, then is refused like a revoked one; `token list`
// shows when. Lifetimes that are no duration are refused with a message.
TEST_F(DaemonSecurityTest, TokensExpireAfterTheirLifetime) {
  const std::string admin = CreateToken("*", "admin");
  Serve("--listen 127.0.0.1:0");
  const auto created = std::chrono::steady_clock::now();
  const std::string brief = CreateToken("*", "read", "--expires-in 5s");
  Result result = Client("map list", "FORESTMAP_TOKEN=" + brief);
  EXPECT_EQ(result.exit_code, 0) << result.err;
  const Result listed = Run("'" FORESTMAPD_PATH "' token list --db '" + db_ + "'");
  EXPECT_NE(listed.out.find("\texpires\t"), std::string::npos) << listed.out;
  EXPECT_NE(listed.out.find("Z\t-\t20"), std::string::npos) << "an expiry time: " << listed.out;
  std::this_thread::sleep_until(created + std::chrono::milliseconds(5200));
  result = Client("map list", "FORESTMAP_TOKEN=" + brief);
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_NE(result.err.find("unknown, revoked or expired"), std::string::npos) << result.err;
  EXPECT_EQ(Client("map list", "FORESTMAP_TOKEN=" + admin).exit_code, 0);  // no expiry

  for (const char* bad : {"0d", "12", "5w", "-3h", "1e9d", "99999999d"}) {
    result = Run("'" FORESTMAPD_PATH "' token create --db '" + db_ + "' --expires-in " + bad);
    EXPECT_NE(result.exit_code, 0) << bad;
    EXPECT_NE(result.err.find("--expires-in must be"), std::string::npos) << bad << result.err;
  }
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
  Serve("--listen 0.0.0.0:0 --http 0.0.0.0:0");
  EXPECT_NE(ReadFile(log_).find("WARNING: listening beyond loopback WITHOUT TLS"),
            std::string::npos)
      << ReadFile(log_);
  EXPECT_NE(ReadFile(log_).find("WARNING: web page listening beyond loopback WITHOUT TLS (the web "
                                "page is plain HTTP"),
            std::string::npos)
      << ReadFile(log_);
  EXPECT_NE(ReadFile(log_).find("WITHOUT TOKENS (anyone who reaches the port can read every map"),
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
