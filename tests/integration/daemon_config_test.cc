// forestmapd's configuration and operation as an operator meets them, through the built binaries:
// the same setting from the command line, the environment and the configuration file (and which
// wins), exit statuses 0 / 1 / 2, start-up failures as one JSON line naming the flag, --version,
// the backup answer for PostgreSQL, the token commands on the configured database, and SIGHUP
// (new TLS certificate for new connections, new log level, one log line, the process lives on).

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "daemon_process.h"
#include "grpc/health/v1/health.grpc.pb.h"
#include "tests/tls_certificate.h"

namespace forestmap {
namespace {

namespace fs = std::filesystem;
using Result = test::CommandResult;
using test::ReadFile;

constexpr auto kLogWait = std::chrono::seconds(10);

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    if (!line.empty()) lines.push_back(line);
  }
  return lines;
}

// A start-up failure under --log-format json: exit 1 and one JSON error line naming `flag`, no
// line of gRPC's own before it. Returns the line's message ("" after a failed check).
std::string OneErrorLine(const Result& result, const std::string& flag) {
  EXPECT_EQ(result.exit_code, 1) << flag;
  const std::vector<std::string> lines = Lines(result.err);
  EXPECT_EQ(lines.size(), 1u) << flag << ":\n" << result.err;
  if (lines.size() != 1) return "";
  const nlohmann::json line = nlohmann::json::parse(lines[0]);
  EXPECT_EQ(line["level"], "error") << lines[0];
  EXPECT_EQ(line["flag"], flag) << lines[0];
  EXPECT_EQ(line["exit_code"], 1) << lines[0];
  return line["msg"].get<std::string>();
}

class DaemonConfigTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("daemon_config_test_" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    db_ = File("maps.db");
    config_ = File("forestmapd.conf");
  }
  void TearDown() override {
    daemon_.Stop();
    fs::remove_all(dir_);
  }

  std::string File(const std::string& name) const { return (dir_ / name).string(); }
  void Write(const std::string& name, const std::string& text) const {
    std::ofstream(dir_ / name) << text;
  }

  // `forestmapd ARGS` with the shell words VAR=value of `env`, no FORESTMAPD_* of the test's
  // caller, and FORESTMAPD_CONFIG set to the test's file (never the machine's /etc one).
  Result Forestmapd(const std::string& args, const std::string& env = "") {
    return test::RunShell(Env(env) + " '" FORESTMAPD_PATH "' " + args, dir_ / "stdout",
                          dir_ / "stderr");
  }
  std::string Env(const std::string& env) const {
    return "env -u FORESTMAPD_DB -u FORESTMAPD_LISTEN -u FORESTMAP_DB -u FORESTMAP_LISTEN "
           "FORESTMAPD_CONFIG='" +
           config_ + "' " + env;
  }

  // Starts forestmapd (the database of the test) and waits for its "serving on" line.
  void Serve(const std::string& args, const std::string& env = "") {
    Write("forestmapd.conf", config_text_);
    log_ = dir_ / ("server" + std::to_string(++starts_) + ".log");
    ASSERT_TRUE(daemon_.Start(
        "--db '" + db_ + "' " + args, log_, dir_ / "pid",
        "-u FORESTMAPD_LISTEN -u FORESTMAP_LISTEN FORESTMAPD_CONFIG='" + config_ + "' " + env));
  }
  // The line of the server's log holding `text`, waiting for it; empty if none came.
  std::string WaitForLog(const std::string& text) const {
    const auto deadline = std::chrono::steady_clock::now() + kLogWait;
    while (std::chrono::steady_clock::now() < deadline) {
      for (const std::string& line : Lines(ReadFile(log_))) {
        if (line.find(text) != std::string::npos) return line;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return "";
  }

  // A self-signed certificate NAME.crt (for 127.0.0.1 and localhost) with its key NAME.key.
  void MakeCertificate(const std::string& name) {
    ASSERT_EQ(test::MakeSelfSignedCertificate(dir_, name, "/CN=" + name,
                                              "subjectAltName=IP:127.0.0.1,DNS:localhost"),
              "");
  }
  // True when a new TLS connection trusting only `ca` gets SERVING from the gRPC health service.
  bool Serving(const std::string& ca) const {
    grpc::SslCredentialsOptions tls;
    tls.pem_root_certs = ReadFile(ca);
    grpc::ChannelArguments args;
    args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);  // a connection of its own
    const auto stub = grpc::health::v1::Health::NewStub(
        grpc::CreateCustomChannel(daemon_.address(), grpc::SslCredentials(tls), args));
    grpc::ClientContext context;
    context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(5));
    grpc::health::v1::HealthCheckResponse response;
    return stub->Check(&context, {}, &response).ok() &&
           response.status() == grpc::health::v1::HealthCheckResponse::SERVING;
  }

  fs::path dir_;
  fs::path log_;
  std::string db_;
  std::string config_;
  std::string config_text_;
  test::DaemonProcess daemon_;
  int starts_ = 0;
};

TEST_F(DaemonConfigTest, CommandLineBeatsEnvironmentBeatsFileBeatsDefault) {
  config_text_ = "# the file\nlisten = \"127.0.0.2:0\"\nlog-format = \"json\"\n";
  Serve("");  // the file alone: its address, JSON lines, and the file named
  const std::string serving = WaitForLog("serving on 127.0.0.2:");
  EXPECT_EQ(serving.rfind("{\"time\"", 0), 0u) << serving;
  EXPECT_NE(serving.find("\"config\":\"" + config_ + "\""), std::string::npos) << serving;
  daemon_.Stop();
  Serve("", "FORESTMAPD_LISTEN=127.0.0.3:0");  // the variable wins; the file's other keys stay
  EXPECT_NE(WaitForLog("serving on 127.0.0.3:").find("{\"time\""), std::string::npos);
  daemon_.Stop();
  Serve("--listen 127.0.0.4:0 --log-format text", "FORESTMAPD_LISTEN=127.0.0.3:0");
  const std::string line = WaitForLog("serving on 127.0.0.4:");
  EXPECT_NE(line, "");
  EXPECT_EQ(line.find('{'), std::string::npos) << line;
  daemon_.Stop();
  // The unit's older name is read, and the new one wins over it.
  Serve("", "FORESTMAP_LISTEN=127.0.0.5:0");
  EXPECT_NE(WaitForLog("serving on 127.0.0.5:"), "");
  daemon_.Stop();
  Serve("", "FORESTMAP_LISTEN=127.0.0.5:0 FORESTMAPD_LISTEN=127.0.0.6:0");
  EXPECT_NE(WaitForLog("serving on 127.0.0.6:"), "");
  daemon_.Stop();
  config_text_.clear();  // an empty file: the default address
  Serve("--listen 127.0.0.1:0");
  EXPECT_NE(WaitForLog("serving on 127.0.0.1:"), "");
}

TEST_F(DaemonConfigTest, UsageErrorsExitTwoNamingTheFlagAndItsSource) {
  Write("forestmapd.conf", "");
  EXPECT_EQ(Forestmapd("--bogus").exit_code, 2);             // CLI11: 109
  EXPECT_EQ(Forestmapd("--max-message-mb 0").exit_code, 2);  // CLI11: 105
  EXPECT_EQ(Forestmapd("--listen").exit_code, 2);            // CLI11: 114
  EXPECT_EQ(Forestmapd("token create --role boss").exit_code, 2);
  const Result from_env = Forestmapd("", "FORESTMAPD_MAX_MESSAGE_MB=0");
  EXPECT_EQ(from_env.exit_code, 2);
  EXPECT_NE(from_env.err.find("--max-message-mb"), std::string::npos) << from_env.err;
  EXPECT_NE(from_env.err.find("environment FORESTMAPD_MAX_MESSAGE_MB"), std::string::npos)
      << from_env.err;

  Write("forestmapd.conf", "max-message-mb = 0\n");
  const Result from_file = Forestmapd("--log-format json");
  EXPECT_EQ(from_file.exit_code, 2);
  const std::vector<std::string> lines = Lines(from_file.err);
  ASSERT_EQ(lines.size(), 1u) << from_file.err;
  const nlohmann::json line = nlohmann::json::parse(lines[0]);
  EXPECT_EQ(line["level"], "error");
  EXPECT_EQ(line["flag"], "--max-message-mb");
  EXPECT_EQ(line["source"], "configuration file " + config_);
  EXPECT_EQ(line["exit_code"], 2);

  Write("forestmapd.conf", "max-mesage-mb = 8\n");
  const Result typo = Forestmapd("");
  EXPECT_EQ(typo.exit_code, 2);
  EXPECT_NE(typo.err.find("unknown setting 'max-mesage-mb'"), std::string::npos) << typo.err;
  const Result missing = Forestmapd("--config '" + File("nowhere.conf") + "'");
  EXPECT_EQ(missing.exit_code, 2);
  EXPECT_NE(missing.err.find("nowhere.conf"), std::string::npos) << missing.err;
}

TEST_F(DaemonConfigTest, StartupFailuresAreOneJsonLineNamingTheFlag) {
  Write("forestmapd.conf", "");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"--listen 256.1.2.3:1", "--listen"},
      {"--db '" + File("no/such/dir/maps.db") + "'", "--db"},
      {"--tls-cert '" + File("none.crt") + "' --tls-key '" + File("none.key") + "'", "--tls-cert"},
      {"--http 256.1.2.3:1 --listen 127.0.0.1:0", "--http"},
  };
  for (const auto& [args, flag] : cases) {
    const std::string db = args.rfind("--db", 0) == 0 ? "" : "--db '" + db_ + "' ";
    const std::string msg = OneErrorLine(Forestmapd(db + "--log-format json " + args), flag);
    EXPECT_EQ(msg.rfind(flag, 0), 0u) << msg;
  }
}

// A port another forestmapd holds, for the gRPC listener or the metrics port: one JSON line that
// names the flag, and no line of gRPC's own before it.
TEST_F(DaemonConfigTest, APortInUseIsOneJsonLineNamingTheFlag) {
  Serve("--listen 127.0.0.1:0");
  const std::string taken = daemon_.address();
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"--listen " + taken, "--listen"},
      {"--listen 127.0.0.1:0 --metrics " + taken, "--metrics"},
  };
  for (const auto& [args, flag] : cases) {
    const std::string msg = OneErrorLine(
        Forestmapd("--db '" + File("second.db") + "' --log-format json " + args), flag);
    EXPECT_EQ(msg.rfind(flag + " " + taken + ": ", 0), 0u) << msg;
  }
  EXPECT_EQ(kill(daemon_.pid(), 0), 0) << "the first server stopped";
}

TEST_F(DaemonConfigTest, VersionHelpAndThePostgresBackupAnswer) {
  Write("forestmapd.conf", "");
  const Result version = Forestmapd("--version");
  EXPECT_EQ(version.exit_code, 0);
  EXPECT_EQ(version.out.rfind("forestmapd " FORESTMAP_EXPECTED_VERSION " (commit ", 0), 0u)
      << version.out;
  EXPECT_NE(version.out.find(", " FORESTMAP_EXPECTED_BUILD_TYPE ")"), std::string::npos)
      << version.out;
  const Result head = test::RunShell("git -C '" FORESTMAP_SOURCE_DIR "' rev-parse --short=12 HEAD",
                                     dir_ / "git.out", dir_ / "git.err");
  const std::string commit = head.exit_code == 0 ? head.out.substr(0, 12) : "unknown";
  EXPECT_NE(version.out.find("(commit " + commit), std::string::npos) << version.out;

  const Result help = Forestmapd("--help");
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_NE(help.out.find("FORESTMAPD_LISTEN"), std::string::npos);

  const Result backup =
      Forestmapd("backup --db postgresql://forestmap@db.example:5432/maps --out x.db");
  EXPECT_EQ(backup.exit_code, 2);
  EXPECT_NE(backup.err.find("pg_dump"), std::string::npos) << backup.err;
  EXPECT_EQ(backup.err.find("not a file"), std::string::npos) << backup.err;
}

TEST_F(DaemonConfigTest, TokenCommandsUseTheConfiguredDatabase) {
  Write("forestmapd.conf", "db = \"" + db_ + "\"\n");
  const Result created = Forestmapd("token create --role admin --note bootstrap");
  ASSERT_EQ(created.exit_code, 0) << created.err;
  EXPECT_EQ(created.out.rfind("fmt_", 0), 0u) << created.out;
  const std::string other = File("other.db");
  EXPECT_EQ(Forestmapd("token create --role read", "FORESTMAPD_DB='" + other + "'").exit_code, 0);
  const Result listed = Forestmapd("token list --db '" + db_ + "'");
  EXPECT_NE(listed.out.find("bootstrap"), std::string::npos) << listed.out;
  EXPECT_EQ(Lines(listed.out).size(), 2u) << listed.out;  // header + the file's db token only
  EXPECT_EQ(Lines(Forestmapd("token list --db '" + other + "'").out).size(), 2u);

  // The listing for scripts: one JSON object per token and line, a revoked one with its time.
  ASSERT_EQ(Forestmapd("token create --role read --map 'plot-*' --expires-in 1d").exit_code, 0);
  ASSERT_EQ(Forestmapd("token revoke 1").exit_code, 0);
  const Result json = Forestmapd("token list --json");
  ASSERT_EQ(json.exit_code, 0) << json.err;
  const std::vector<std::string> tokens = Lines(json.out);
  ASSERT_EQ(tokens.size(), 2u) << json.out;
  const nlohmann::json first = nlohmann::json::parse(tokens[0]);
  EXPECT_EQ(first["id"], 1);
  EXPECT_EQ(first["role"], "admin");
  EXPECT_EQ(first["maps"], "*");
  EXPECT_EQ(first["note"], "bootstrap");
  EXPECT_GT(first["revoked_unix_ms"].get<int64_t>(), first["created_unix_ms"].get<int64_t>() - 1);
  EXPECT_TRUE(first["expires_unix_ms"].is_null()) << tokens[0];
  const nlohmann::json second = nlohmann::json::parse(tokens[1]);
  EXPECT_EQ(second["role"], "read");
  EXPECT_EQ(second["maps"], "plot-*");
  EXPECT_TRUE(second["revoked_unix_ms"].is_null()) << tokens[1];
  EXPECT_NEAR(second["expires_unix_ms"].get<double>() - second["created_unix_ms"].get<double>(),
              86'400'000.0, 60'000.0);
}

TEST_F(DaemonConfigTest, SighupReloadsTlsFilesAndLogLevel) {
  MakeCertificate("first");
  MakeCertificate("second");
  fs::copy_file(File("first.crt"), File("server.crt"));
  fs::copy_file(File("first.key"), File("server.key"));
  config_text_ = "log-level = \"info\"\ntls-cert = \"" + File("server.crt") + "\"\ntls-key = \"" +
                 File("server.key") + "\"\n";
  Serve("--listen 127.0.0.1:0");
  EXPECT_TRUE(Serving(File("first.crt")));
  EXPECT_FALSE(Serving(File("second.crt")));

  // Renewed files and a louder log level, then SIGHUP.
  fs::copy_file(File("second.crt"), File("server.crt"), fs::copy_options::overwrite_existing);
  fs::copy_file(File("second.key"), File("server.key"), fs::copy_options::overwrite_existing);
  Write("forestmapd.conf", "log-level = \"debug\"\ntls-cert = \"" + File("server.crt") +
                               "\"\ntls-key = \"" + File("server.key") + "\"\n");
  ASSERT_EQ(kill(daemon_.pid(), SIGHUP), 0);
  const std::string reloaded = WaitForLog("SIGHUP: reloaded");
  EXPECT_NE(reloaded.find("log level debug (was info)"), std::string::npos) << reloaded;
  EXPECT_NE(reloaded.find("TLS certificate CN=second"), std::string::npos) << reloaded;
  EXPECT_TRUE(Serving(File("second.crt")));  // a new connection: the new certificate
  EXPECT_FALSE(Serving(File("first.crt")));
  EXPECT_EQ(kill(daemon_.pid(), 0), 0) << "forestmapd died of SIGHUP";
  // Health checks log at debug level: their lines appear now.
  EXPECT_NE(WaitForLog("rpc=grpc.health.v1.Health/Check").find(" debug "), std::string::npos);

  // A key that does not match, and a change that needs a restart: reported, the rest kept.
  fs::copy_file(File("first.key"), File("server.key"), fs::copy_options::overwrite_existing);
  Write("forestmapd.conf", "log-level = \"debug\"\nkeep-versions = 3\ntls-cert = \"" +
                               File("server.crt") + "\"\ntls-key = \"" + File("server.key") +
                               "\"\n");
  ASSERT_EQ(kill(daemon_.pid(), SIGHUP), 0);
  const std::string refused = WaitForLog("NOT reloaded");
  EXPECT_NE(refused.find("is not the key of --tls-cert"), std::string::npos) << refused;
  EXPECT_NE(refused.find("applied only by a restart: --keep-versions"), std::string::npos)
      << refused;
  EXPECT_TRUE(Serving(File("second.crt")));
  EXPECT_EQ(kill(daemon_.pid(), 0), 0);
}

}  // namespace
}  // namespace forestmap
