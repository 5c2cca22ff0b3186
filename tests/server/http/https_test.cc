// The web page and the metrics port over HTTPS with forestmapd's TLS credentials (the gRPC
// port's): certificates made here with the openssl CLI; in-process listeners on port 0. A client
// with a certificate signed by the client CA gets the page; one without, or a plain HTTP client,
// gets nothing; a reload serves the new certificate to new connections; 50 connections that
// never handshake leave the page answering; a client dripping its hello is cut after the
// handshake limit (5 s) instead of holding a worker as long as it drips.

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <future>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "server/app/recent_answers.h"
#include "server/http/http_listen.h"
#include "server/http/http_page.h"
#include "server/http/metrics_http.h"
#include "server/ops/tls.h"
#include "storage/sqlite/store.h"
#include "storage/token_store.h"
#include "tests/server/http/closed_by_server.h"
#include "tests/server/http_get.h"
#include "tests/tls_certificate.h"

namespace forestmap::server {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// A TCP connection from `source` to 127.0.0.1:port that sends nothing; -1 when it cannot
// connect.
int Connect(int port, const char* source = "127.0.0.1") {
  const int sock = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in from{};
  from.sin_family = AF_INET;
  inet_pton(AF_INET, source, &from.sin_addr);
  if (bind(sock, reinterpret_cast<sockaddr*>(&from), sizeof(from)) != 0) {
    close(sock);
    return -1;
  }
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<uint16_t>(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (connect(sock, reinterpret_cast<sockaddr*>(&address), sizeof(address)) != 0) {
    close(sock);
    return -1;
  }
  return sock;
}

class HttpsTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(fs::temp_directory_path() / ("https_test_" + std::to_string(getpid())));
    fs::remove_all(*dir_);
    fs::create_directories(*dir_);
    MakeCertificate("server", "/CN=forestmapd-test", "subjectAltName=IP:127.0.0.1");
    MakeCertificate("renewed", "/CN=forestmapd-renewed", "subjectAltName=IP:127.0.0.1");
    MakeCertificate("client", "/CN=drone-7", "extendedKeyUsage=clientAuth");
    MakeCertificate("stranger", "/CN=stranger", "extendedKeyUsage=clientAuth");
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
  }
  // A self-signed certificate NAME.crt with key NAME.key (valid one day).
  static void MakeCertificate(const std::string& name, const std::string& subject,
                              const std::string& extension) {
    ASSERT_EQ(test::MakeSelfSignedCertificate(*dir_, name, subject, extension), "");
  }
  static std::string File(const std::string& name) { return (*dir_ / name).string(); }

  // The page over HTTPS with the server certificate; `client_ca`: client certificates required.
  void Serve(const std::string& client_ca) {
    tls_ = std::make_unique<TlsCredentials>(
        TlsFiles{File("server.crt"), File("server.key"), client_ca});
    page_ = std::make_unique<HttpPage>(store_, answers_, "127.0.0.1:0", &tokens_,
                                       [this](SSL_CTX& ctx) { return tls_->SetUpHttps(ctx); });
    port_ = std::stoi(page_->address().substr(page_->address().rfind(':') + 1));
  }
  test::TlsClientFiles Client(const std::string& name, const std::string& ca = "server") const {
    return {File(ca + ".crt"), name.empty() ? "" : File(name + ".crt"),
            name.empty() ? "" : File(name + ".key")};
  }

  static fs::path* dir_;
  storage::SqliteMapStore store_{":memory:"};
  storage::TokenStore tokens_{":memory:"};
  RecentAnswers answers_;
  std::unique_ptr<TlsCredentials> tls_;  // outlives the page
  std::unique_ptr<HttpPage> page_;
  int port_ = 0;
};

fs::path* HttpsTest::dir_ = nullptr;

TEST_F(HttpsTest, ClientCertificatesAreRequiredAsOnTheGrpcPort) {
  store_.CreateMap("plot-1", "", "");
  Serve(File("client.crt"));  // the self-signed client certificate is its own CA
  EXPECT_EQ(page_->url().rfind("https://", 0), 0u) << page_->url();
  const test::HttpAnswer drone = test::HttpsGet("127.0.0.1", port_, "/api/maps", Client("client"));
  EXPECT_EQ(drone.status, 200) << drone.error;
  EXPECT_NE(drone.body.find("plot-1"), std::string::npos) << drone.body;
  EXPECT_EQ(test::HttpsGet("127.0.0.1", port_, "/", Client("client")).status, 200);

  const test::HttpAnswer anonymous = test::HttpsGet("127.0.0.1", port_, "/api/maps", Client(""));
  EXPECT_FALSE(anonymous.ok) << anonymous.status;
  EXPECT_FALSE(test::HttpsGet("127.0.0.1", port_, "/api/maps", Client("stranger")).ok);
  const test::HttpAnswer plain = test::HttpGet("127.0.0.1", port_, "/api/maps");
  EXPECT_FALSE(plain.ok && plain.status == 200) << plain.body;
  // A client that does not trust the server's certificate stops at the handshake.
  EXPECT_FALSE(test::HttpsGet("127.0.0.1", port_, "/api/maps", Client("client", "renewed")).ok);
}

TEST_F(HttpsTest, TheFirstVisitCookieIsSecureOverHttps) {
  const std::string reader = tokens_.Create("*", storage::Role::kRead).secret;
  Serve("");
  EXPECT_EQ(test::HttpsGet("127.0.0.1", port_, "/api/maps", Client("")).status, 401);
  const test::HttpAnswer first =
      test::HttpsGet("127.0.0.1", port_, "/?token=" + reader, Client(""));
  EXPECT_EQ(first.status, 303);
  EXPECT_NE(first.set_cookie.find("forestmap_token=" + reader + ";"), std::string::npos);
  EXPECT_NE(first.set_cookie.find("; Secure"), std::string::npos) << first.set_cookie;
  EXPECT_EQ(test::HttpsGet("127.0.0.1", port_, "/api/maps", Client(""), reader).status, 200);
}

TEST_F(HttpsTest, AReloadServesTheNewCertificateToNewConnections) {
  Serve("");
  EXPECT_TRUE(test::HttpsGet("127.0.0.1", port_, "/api/maps", Client("")).ok);
  EXPECT_FALSE(test::HttpsGet("127.0.0.1", port_, "/api/maps", Client("", "renewed")).ok);
  tls_->Reload(TlsFiles{File("renewed.crt"), File("renewed.key"), ""});
  const test::HttpAnswer renewed =
      test::HttpsGet("127.0.0.1", port_, "/api/maps", Client("", "renewed"));
  EXPECT_EQ(renewed.status, 200) << renewed.error;
  EXPECT_FALSE(test::HttpsGet("127.0.0.1", port_, "/api/maps", Client("")).ok);
}

// 50 connections of one client (127.0.0.2) that never send a hello: 8 hold a worker each until
// the read timeout (2 s), the others are closed at once (a plain 503 would be garbage to a TLS
// client); other clients are answered meanwhile.
TEST_F(HttpsTest, IdleConnectionsThatNeverHandshakeDoNotStallThePage) {
  Serve(File("client.crt"));
  std::vector<int> idle;
  for (int i = 0; i < 50; ++i) idle.push_back(Connect(port_, "127.0.0.2"));
  for (const int sock : idle) ASSERT_GE(sock, 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(100));  // all of them accepted
  int closed = 0;
  for (const int sock : idle) closed += test::ClosedByServer(sock) ? 1 : 0;
  EXPECT_EQ(closed, 50 - kConnectionsPerClient);
  const Clock::time_point start = Clock::now();
  auto answer = std::async(std::launch::async, [this] {
    return test::HttpsGet("127.0.0.1", port_, "/api/maps", Client("client"));
  });
  ASSERT_EQ(answer.wait_for(std::chrono::seconds(10)), std::future_status::ready);
  EXPECT_EQ(answer.get().status, 200);
  const double seconds = SecondsSince(start);
  std::printf("HTTPS answered in %.0f ms beside 50 connections that never handshake\n",
              seconds * 1000);
  EXPECT_LT(seconds, 1.0);
  for (const int sock : idle) close(sock);
}

// A hello dripped one byte every 250 ms never waits 2 s for a byte, so only the handshake limit
// ends it.
TEST_F(HttpsTest, AHandshakeDrippedByteByByteIsCutAtTheLimit) {
  Serve("");
  const int sock = Connect(port_);
  ASSERT_GE(sock, 0);
  const unsigned char record[] = {0x16, 0x03, 0x01, 0x02, 0x00};  // handshake, 512 bytes to come
  ASSERT_EQ(send(sock, record, sizeof record, MSG_NOSIGNAL), static_cast<ssize_t>(sizeof record));
  const Clock::time_point start = Clock::now();
  bool closed = false;
  while (!closed && SecondsSince(start) < 20) {
    const unsigned char byte = 0x01;
    closed = send(sock, &byte, 1, MSG_NOSIGNAL) != 1 || test::ClosedByServer(sock);
    if (!closed) std::this_thread::sleep_for(std::chrono::milliseconds(250));
  }
  const double seconds = SecondsSince(start);
  close(sock);
  std::printf("a dripped handshake was cut after %.1f s\n", seconds);
  EXPECT_TRUE(closed);
  EXPECT_GT(seconds, 4.0);
  EXPECT_LT(seconds, 8.0);
  // The page answers afterwards.
  EXPECT_EQ(test::HttpsGet("127.0.0.1", port_, "/api/maps", Client("")).status, 200);
}

TEST_F(HttpsTest, TheMetricsPortServesHttpsWithTheSameCredentials) {
  tls_ = std::make_unique<TlsCredentials>(
      TlsFiles{File("server.crt"), File("server.key"), File("client.crt")});
  MetricsHttpServer metrics(
      "127.0.0.1:0", [] { return std::string("forestmap_ready 1\n"); },
      [] { return std::make_pair(true, std::string()); },
      [this](SSL_CTX& ctx) { return tls_->SetUpHttps(ctx); });
  EXPECT_EQ(metrics.url().rfind("https://", 0), 0u);
  const test::HttpAnswer scrape =
      test::HttpsGet("127.0.0.1", metrics.port(), "/metrics", Client("client"));
  EXPECT_EQ(scrape.status, 200) << scrape.error;
  EXPECT_EQ(scrape.body, "forestmap_ready 1\n");
  EXPECT_FALSE(test::HttpsGet("127.0.0.1", metrics.port(), "/healthz", Client("")).ok);
  EXPECT_FALSE(test::HttpGet("127.0.0.1", metrics.port(), "/healthz").status == 200);
}

}  // namespace
}  // namespace forestmap::server
