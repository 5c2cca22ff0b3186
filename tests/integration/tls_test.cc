// TLS end to end through the client library: certificates made here with the openssl CLI (a
// self-signed server certificate for 127.0.0.1 and one for a client), an in-process server on
// port 0. A plaintext client is refused, a TLS client that trusts the certificate works, one that
// does not is refused; with --tls-client-ca a client without a certificate is refused. Tokens go
// through the same channel. Reload (forestmapd's SIGHUP) gives new connections the new
// certificate, and a reload that fails keeps the old one.

#include "server/ops/tls.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include "client/lib/forestmap_client.h"
#include "server/grpc/server.h"
#include "server/grpc/service.h"
#include "server/ops/auth.h"
#include "storage/sqlite/store.h"
#include "storage/token_store.h"
#include "tests/tls_certificate.h"

namespace forestmap {
namespace {

namespace fs = std::filesystem;

class TlsTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    std::string name = "tls_test_";
    name.append(std::to_string(getpid()));
    dir_ = new fs::path(fs::temp_directory_path() / name);
    fs::remove_all(*dir_);
    fs::create_directories(*dir_);
    MakeCertificate("server", "/CN=forestmapd-test", "subjectAltName=IP:127.0.0.1,DNS:localhost");
    MakeCertificate("client", "/CN=drone-7", "extendedKeyUsage=clientAuth");
    MakeCertificate("stranger", "/CN=stranger", "subjectAltName=IP:127.0.0.1");
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

  // Starts a TLS server; `client_ca` non-empty requires client certificates.
  void Serve(const std::string& client_ca = "") {
    server::ServiceOptions service_options;
    service_options.authorizer = &authorizer_;
    service_ = std::make_unique<server::ForestMapService>(store_, service_options);
    tls_ = std::make_unique<server::TlsCredentials>(
        server::TlsFiles{File("server.crt"), File("server.key"), client_ca});
    server::ServerOptions options;
    options.credentials = tls_->credentials();
    runner_ = std::make_unique<server::ServerRunner>("127.0.0.1:0", *service_, options);
  }

  client::ClientOptions Tls(const std::string& ca) const {
    client::ClientOptions options;
    options.connect_timeout = 2.0;
    options.tls_ca = ca;
    options.tls = true;
    return options;
  }

  static fs::path* dir_;
  storage::SqliteMapStore store_{":memory:"};
  storage::TokenStore tokens_{":memory:"};
  server::Authorizer authorizer_{&tokens_};
  std::unique_ptr<server::TlsCredentials> tls_;  // outlives the server
  std::unique_ptr<server::ForestMapService> service_;
  std::unique_ptr<server::ServerRunner> runner_;
};

fs::path* TlsTest::dir_ = nullptr;

TEST_F(TlsTest, PlaintextClientIsRefusedTlsClientWorks) {
  Serve();
  client::ClientOptions plaintext;
  plaintext.connect_timeout = 2.0;
  client::ForestMapClient insecure(runner_->address(), plaintext);
  EXPECT_THROW(insecure.ListMaps(), client::RpcError);

  client::ForestMapClient secure(runner_->address(), Tls(File("server.crt")));
  EXPECT_EQ(secure.CreateMap("plot-1").name(), "plot-1");
  EXPECT_EQ(secure.ListMaps().size(), 1u);
}

TEST_F(TlsTest, AClientThatDoesNotTrustTheCertificateIsRefused) {
  Serve();
  client::ForestMapClient wrong_ca(runner_->address(), Tls(File("stranger.crt")));
  EXPECT_THROW(wrong_ca.ListMaps(), client::RpcError);
}

TEST_F(TlsTest, ClientCertificatesAreRequiredWithAClientCa) {
  Serve(File("client.crt"));  // the self-signed client certificate is its own CA
  client::ForestMapClient anonymous(runner_->address(), Tls(File("server.crt")));
  EXPECT_THROW(anonymous.ListMaps(), client::RpcError);

  client::ClientOptions with_cert = Tls(File("server.crt"));
  with_cert.tls_cert = File("stranger.crt");
  with_cert.tls_key = File("stranger.key");
  client::ForestMapClient stranger(runner_->address(), with_cert);
  EXPECT_THROW(stranger.ListMaps(), client::RpcError);

  with_cert.tls_cert = File("client.crt");
  with_cert.tls_key = File("client.key");
  client::ForestMapClient drone(runner_->address(), with_cert);
  EXPECT_TRUE(drone.ListMaps().empty());
}

TEST_F(TlsTest, TokensTravelOverTls) {
  Serve();
  const std::string admin = tokens_.Create("*", storage::Role::kAdmin).secret;
  client::ForestMapClient no_token(runner_->address(), Tls(File("server.crt")));
  try {
    no_token.ListMaps();
    FAIL() << "ListMaps without a token succeeded";
  } catch (const client::RpcError& e) {
    EXPECT_EQ(e.code(), grpc::StatusCode::UNAUTHENTICATED) << e.what();
  }
  client::ClientOptions options = Tls(File("server.crt"));
  options.token = admin;
  client::ForestMapClient with_token(runner_->address(), options);
  EXPECT_EQ(with_token.CreateMap("plot-2").name(), "plot-2");
}

TEST_F(TlsTest, ReloadServesTheNewCertificateToNewConnections) {
  Serve();
  {
    client::ForestMapClient before(runner_->address(), Tls(File("server.crt")));
    EXPECT_TRUE(before.ListMaps().empty());
  }
  // "stranger" holds a certificate for 127.0.0.1 too, from another (self-signed) issuer.
  EXPECT_NE(tls_->Reload({File("stranger.crt"), File("stranger.key"), ""}).find("CN=stranger"),
            std::string::npos);
  client::ForestMapClient old_trust(runner_->address(), Tls(File("server.crt")));
  EXPECT_THROW(old_trust.ListMaps(), client::RpcError);
  client::ForestMapClient new_trust(runner_->address(), Tls(File("stranger.crt")));
  EXPECT_TRUE(new_trust.ListMaps().empty());
}

TEST_F(TlsTest, AFailedReloadKeepsTheCertificate) {
  Serve();
  // A key of another certificate, a missing file, and turning on client certificates.
  EXPECT_THROW(tls_->Reload({File("server.crt"), File("stranger.key"), ""}), std::runtime_error);
  EXPECT_THROW(tls_->Reload({File("server.crt"), File("missing.key"), ""}), std::runtime_error);
  EXPECT_THROW(tls_->Reload({File("server.crt"), File("server.key"), File("client.crt")}),
               std::runtime_error);
  EXPECT_NE(tls_->Describe().find("CN=forestmapd-test"), std::string::npos) << tls_->Describe();
  client::ForestMapClient trusting(runner_->address(), Tls(File("server.crt")));
  EXPECT_TRUE(trusting.ListMaps().empty());
}

TEST_F(TlsTest, MissingNonPemOrMismatchedFilesAreNamed) {
  try {
    server::TlsCredentials({"/nonexistent/server.crt", "/nonexistent/server.key", ""});
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/server"), std::string::npos) << e.what();
  }
  EXPECT_THROW(server::TlsCredentials({"", "", ""}), std::runtime_error);
  try {
    server::TlsCredentials({File("server.crt"), File("client.key"), ""});
    FAIL() << "a key of another certificate was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("is not the key of --tls-cert"), std::string::npos)
        << e.what();
  }
}

TEST(TlsFiles, LoopbackAddresses) {
  EXPECT_TRUE(server::IsLoopback("127.0.0.1:50051"));
  EXPECT_TRUE(server::IsLoopback("[::1]:50051"));
  EXPECT_TRUE(server::IsLoopback("localhost:1"));
  EXPECT_FALSE(server::IsLoopback("0.0.0.0:50051"));
  EXPECT_FALSE(server::IsLoopback("[::]:50051"));
  EXPECT_FALSE(server::IsLoopback("10.1.2.3:50051"));
}

}  // namespace
}  // namespace forestmap
