// forestmapd's web page and metrics port over HTTPS as an operator runs them (the built binary):
// with --tls-cert, --tls-key and --tls-client-ca the page serves HTTPS with the gRPC port's
// certificate and requires a client certificate signed by the client CA, as gRPC does: a client
// with one and a token reads a map's trees; without a certificate the handshake fails; plain HTTP
// gets nothing; without a token the page answers 401. --metrics-tls does the same for the
// metrics port; a plain metrics port beyond loopback, and --metrics-tls without TLS, are said.

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <regex>
#include <string>
#include <vector>

#include "daemon_process.h"
#include "storage/sqlite/store.h"
#include "tests/server/http_get.h"
#include "tests/tls_certificate.h"

namespace forestmap {
namespace {

namespace fs = std::filesystem;
using test::CommandResult;
using test::ReadFile;

constexpr int kTrees = 25;

class DaemonHttpsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("daemon_https_test_" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    MakeCertificate("server", "/CN=forestmapd-test", "subjectAltName=IP:127.0.0.1");
    MakeCertificate("client", "/CN=drone-7", "extendedKeyUsage=clientAuth");  // its own CA
    storage::SqliteMapStore store(File("maps.db"));
    store.CreateMap("plot-1", "", "");
    std::vector<storage::TreeRecord> trees(kTrees);
    for (int i = 0; i < kTrees; ++i) {
      trees[i].x = i * 3.0;
      trees[i].y = (i % 5) * 4.0;
    }
    store.WriteTrees("plot-1", trees, storage::WriteMode::kAppend);
  }
  void TearDown() override {
    daemon_.Stop();
    fs::remove_all(dir_);
  }

  std::string File(const std::string& name) const { return (dir_ / name).string(); }
  CommandResult Run(const std::string& command) {
    return test::RunShell(command, dir_ / "stdout", dir_ / "stderr");
  }
  void MakeCertificate(const std::string& name, const std::string& subject,
                       const std::string& extension) {
    ASSERT_EQ(test::MakeSelfSignedCertificate(dir_, name, subject, extension), "");
  }
  // forestmapd on maps.db with TLS, client certificates, `flags`; the log's text (a new log for
  // each start: the last one's "serving on" must not be read as this one's).
  std::string Serve(const std::string& flags) {
    const fs::path log = dir_ / ("server" + std::to_string(++starts_) + ".log");
    EXPECT_TRUE(daemon_.Start("--db '" + File("maps.db") + "' --listen 127.0.0.1:0 --tls-cert '" +
                                  File("server.crt") + "' --tls-key '" + File("server.key") +
                                  "' --tls-client-ca '" + File("client.crt") + "' " + flags,
                              log, dir_ / "pid"));
    return ReadFile(log);
  }
  static int PortOf(const std::string& log, const std::string& pattern) {
    std::smatch match;
    return std::regex_search(log, match, std::regex(pattern)) ? std::stoi(match[1].str()) : 0;
  }
  test::TlsClientFiles WithCertificate() const {
    return {File("server.crt"), File("client.crt"), File("client.key")};
  }

  fs::path dir_;
  int starts_ = 0;
  test::DaemonProcess daemon_;
};

TEST_F(DaemonHttpsTest, ThePageNeedsAClientCertificateAndATokenAsTheGrpcPortDoes) {
  const CommandResult created = Run("'" FORESTMAPD_PATH "' token create --db '" + File("maps.db") +
                                    "' --map 'plot-*' --role read");
  ASSERT_EQ(created.exit_code, 0) << created.err;
  const std::string token = created.out.substr(0, created.out.find_last_not_of("\n") + 1);
  const std::string log = Serve("--http 127.0.0.1:0");
  const int port = PortOf(log, R"(web page on https://127\.0\.0\.1:(\d+)/)");
  ASSERT_GT(port, 0) << log;

  const test::HttpAnswer page = test::HttpsGet("127.0.0.1", port, "/", WithCertificate(), token);
  EXPECT_EQ(page.status, 200) << page.error;
  EXPECT_NE(page.content_type.find("text/html"), std::string::npos);
  const test::HttpAnswer trees =
      test::HttpsGet("127.0.0.1", port, "/api/maps/plot-1/trees", WithCertificate(), token);
  ASSERT_EQ(trees.status, 200) << trees.error << trees.body;
  EXPECT_EQ(nlohmann::json::parse(trees.body)["trees"].size(), static_cast<size_t>(kTrees));
  // Tokens as before: none -> 401, over the verified connection too.
  EXPECT_EQ(test::HttpsGet("127.0.0.1", port, "/api/maps/plot-1/trees", WithCertificate()).status,
            401);
  // No client certificate: the handshake fails, nothing is answered.
  const test::HttpAnswer anonymous = test::HttpsGet("127.0.0.1", port, "/api/maps/plot-1/trees",
                                                    {File("server.crt"), "", ""}, token);
  EXPECT_FALSE(anonymous.ok) << anonymous.status << " " << anonymous.body;
  // Plain HTTP, with the token in the address as a careless client sends it: nothing.
  const test::HttpAnswer plain =
      test::HttpGet("127.0.0.1", port, "/api/maps/plot-1/trees?token=" + token);
  EXPECT_FALSE(plain.ok && plain.status == 200) << plain.body;
  EXPECT_EQ(plain.body.find("trees"), std::string::npos);
}

TEST_F(DaemonHttpsTest, MetricsTlsServesTheMetricsPortOverHttps) {
  const std::string log = Serve("--metrics 127.0.0.1:0 --metrics-tls");
  const int port = PortOf(log, R"(metrics on https://127\.0\.0\.1:(\d+)/metrics)");
  ASSERT_GT(port, 0) << log;
  const test::HttpAnswer scrape = test::HttpsGet("127.0.0.1", port, "/metrics", WithCertificate());
  EXPECT_EQ(scrape.status, 200) << scrape.error;
  EXPECT_NE(scrape.body.find("forestmap_ready"), std::string::npos);
  EXPECT_FALSE(test::HttpsGet("127.0.0.1", port, "/healthz", {File("server.crt"), "", ""}).ok);
  EXPECT_NE(test::HttpGet("127.0.0.1", port, "/healthz").status, 200);
}

TEST_F(DaemonHttpsTest, ExposedListenersAreWarnedAboutOnlyWhenPlain) {
  const CommandResult created =
      Run("'" FORESTMAPD_PATH "' token create --db '" + File("maps.db") + "' --role admin");
  ASSERT_EQ(created.exit_code, 0) << created.err;
  // TLS and tokens: the page beyond loopback is fine; the plain metrics port is not.
  const std::string log = Serve("--http 0.0.0.0:0 --metrics 0.0.0.0:0");
  EXPECT_EQ(log.find("WARNING: web page"), std::string::npos) << log;
  EXPECT_NE(log.find("WARNING: metrics port listening beyond loopback WITHOUT TLS"),
            std::string::npos)
      << log;
  daemon_.Stop();
  const std::string quiet = Serve("--http 0.0.0.0:0 --metrics 0.0.0.0:0 --metrics-tls");
  EXPECT_EQ(quiet.find("WARNING"), std::string::npos) << quiet;
}

TEST_F(DaemonHttpsTest, MetricsTlsWithoutTlsIsAStartUpError) {
  const CommandResult result = Run("timeout 15 '" FORESTMAPD_PATH "' --db '" + File("other.db") +
                                   "' --listen 127.0.0.1:0 --metrics 127.0.0.1:0 --metrics-tls");
  EXPECT_EQ(result.exit_code, 1) << result.err;
  EXPECT_NE(result.err.find("--metrics-tls needs --tls-cert and --tls-key"), std::string::npos)
      << result.err;
}

}  // namespace
}  // namespace forestmap
