#include "server/ops/tls.h"

#include <grpc/grpc.h>
#include <grpc/grpc_security.h>
#include <openssl/err.h>
#include <openssl/pem.h>
#include <openssl/ssl.h>
#include <openssl/x509.h>

#include <ctime>
#include <fstream>
#include <memory>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace forestmap::server {
namespace {

std::string ReadPem(const std::string& path, const char* flag) {
  std::ifstream file(path, std::ios::binary);
  if (!file) throw std::runtime_error(std::string(flag) + ": cannot read " + path);
  std::ostringstream text;
  text << file.rdbuf();
  if (text.str().find("-----BEGIN ") == std::string::npos) {
    throw std::runtime_error(std::string(flag) + ": " + path + " is not a PEM file");
  }
  return text.str();
}

template <typename T, void (*Free)(T*)>
struct Freer {
  void operator()(T* p) const { Free(p); }
};
using Bio = std::unique_ptr<BIO, Freer<BIO, BIO_free_all>>;
using Certificate = std::unique_ptr<X509, Freer<X509, X509_free>>;
using Key = std::unique_ptr<EVP_PKEY, Freer<EVP_PKEY, EVP_PKEY_free>>;

Bio MemoryBio(const std::string& pem) {
  return Bio(BIO_new_mem_buf(pem.data(), static_cast<int>(pem.size())));
}

// "CN=forestmapd (not after 2027-01-01T00:00:00Z)".
std::string Description(X509* certificate) {
  char subject[256] = "";
  X509_NAME_oneline(X509_get_subject_name(certificate), subject, sizeof subject);
  std::tm not_after{};
  char expiry[32] = "?";
  if (ASN1_TIME_to_tm(X509_get0_notAfter(certificate), &not_after) == 1) {
    std::strftime(expiry, sizeof expiry, "%Y-%m-%dT%H:%M:%SZ", &not_after);
  }
  const std::string name = subject[0] == '/' ? subject + 1 : subject;
  return name + " (not after " + expiry + ")";
}

// The files of one Reload parsed for OpenSSL, as the HTTPS listeners serve them.
struct HttpsIdentity {
  Certificate leaf;
  STACK_OF(X509) * chain = sk_X509_new_null();  // the certificates after the first
  Key key;
  X509_STORE* client_ca = nullptr;           // with --tls-client-ca: what verifies a client
  STACK_OF(X509_NAME) * ca_names = nullptr;  // and the names the server asks for
  HttpsIdentity() = default;
  HttpsIdentity(const HttpsIdentity&) = delete;
  HttpsIdentity& operator=(const HttpsIdentity&) = delete;
  ~HttpsIdentity() {
    sk_X509_pop_free(chain, X509_free);
    X509_STORE_free(client_ca);
    sk_X509_NAME_pop_free(ca_names, X509_NAME_free);
  }
};

// The PEM texts of `files`, checked: the key belongs to the (first) certificate.
struct Pem {
  std::string cert, key, client_ca, description;
  std::shared_ptr<const HttpsIdentity> https;
};

std::shared_ptr<const HttpsIdentity> ParseIdentity(const Pem& pem, const TlsFiles& files) {
  auto identity = std::make_shared<HttpsIdentity>();
  const Bio certificates = MemoryBio(pem.cert);
  identity->leaf.reset(PEM_read_bio_X509(certificates.get(), nullptr, nullptr, nullptr));
  while (X509* next = PEM_read_bio_X509(certificates.get(), nullptr, nullptr, nullptr)) {
    sk_X509_push(identity->chain, next);
  }
  identity->key.reset(PEM_read_bio_PrivateKey(MemoryBio(pem.key).get(), nullptr, nullptr, nullptr));
  if (!pem.client_ca.empty()) {
    identity->client_ca = X509_STORE_new();
    identity->ca_names = sk_X509_NAME_new_null();
    const Bio authorities = MemoryBio(pem.client_ca);
    while (X509* ca = PEM_read_bio_X509(authorities.get(), nullptr, nullptr, nullptr)) {
      X509_STORE_add_cert(identity->client_ca, ca);
      sk_X509_NAME_push(identity->ca_names, X509_NAME_dup(X509_get_subject_name(ca)));
      X509_free(ca);
    }
    if (sk_X509_NAME_num(identity->ca_names) == 0) {
      ERR_clear_error();
      throw std::runtime_error("--tls-client-ca: " + files.client_ca + " holds no certificate");
    }
  }
  ERR_clear_error();  // the end of each PEM text reads as an error
  return identity;
}

Pem ReadTlsFiles(const TlsFiles& files) {
  if (files.cert.empty() || files.key.empty()) {
    throw std::runtime_error("TLS needs both --tls-cert and --tls-key");
  }
  Pem pem{ReadPem(files.cert, "--tls-cert"), ReadPem(files.key, "--tls-key"), "", "", nullptr};
  if (!files.client_ca.empty()) pem.client_ca = ReadPem(files.client_ca, "--tls-client-ca");
  const Certificate certificate(
      PEM_read_bio_X509(MemoryBio(pem.cert).get(), nullptr, nullptr, nullptr));
  const Key key(PEM_read_bio_PrivateKey(MemoryBio(pem.key).get(), nullptr, nullptr, nullptr));
  const bool matches = certificate && key && X509_check_private_key(certificate.get(), key.get());
  ERR_clear_error();
  if (!certificate) throw std::runtime_error("--tls-cert: " + files.cert + " holds no certificate");
  if (!key) throw std::runtime_error("--tls-key: " + files.key + " holds no private key");
  if (!matches) {
    throw std::runtime_error("--tls-key: " + files.key + " is not the key of --tls-cert " +
                             files.cert);
  }
  pem.description = Description(certificate.get());
  pem.https = ParseIdentity(pem, files);
  return pem;
}

grpc_ssl_server_certificate_config* CertificateConfig(const Pem& pem) {
  const grpc_ssl_pem_key_cert_pair pair{pem.key.c_str(), pem.cert.c_str()};
  // gRPC 1.51 asserts that a fetched config has root certificates even when it requests no
  // client certificate (ssl_security_connector.cc); then they are never used to verify a
  // client, so the server's own chain stands in.
  const std::string& roots = pem.client_ca.empty() ? pem.cert : pem.client_ca;
  return grpc_ssl_server_certificate_config_create(roots.c_str(), &pair, 1);  // copies the texts
}

// grpc::ServerCredentials around C credentials: gRPC's Server adds its port through them.
class CoreServerCredentials final : public grpc::ServerCredentials {
 public:
  explicit CoreServerCredentials(grpc_server_credentials* credentials)
      : credentials_(credentials) {}
  ~CoreServerCredentials() override { grpc_server_credentials_release(credentials_); }
  void SetAuthMetadataProcessor(const std::shared_ptr<grpc::AuthMetadataProcessor>&) override {
    throw std::logic_error(
        "TlsCredentials: no AuthMetadataProcessor (tokens are checked "
        "by the service)");
  }

 private:
  int AddPortToServer(const std::string& address, grpc_server* server) override {
    return grpc_server_add_http2_port(server, address.c_str(), credentials_);
  }
  grpc_server_credentials* credentials_;
};

}  // namespace

struct TlsCredentials::State {
  bool client_ca = false;
  std::mutex mutex;
  grpc_ssl_server_certificate_config* next = nullptr;  // for the next handshake; guarded
  std::string description;                             // guarded
  std::shared_ptr<const HttpsIdentity> https;          // of HTTPS handshakes; guarded
  State() { grpc_init(); }
  ~State() {
    if (next != nullptr) grpc_ssl_server_certificate_config_destroy(next);
    grpc_shutdown();
  }
  State(const State&) = delete;
  State& operator=(const State&) = delete;

  // gRPC's fetcher: called before each handshake, from gRPC's threads.
  static grpc_ssl_certificate_config_reload_status Fetch(
      void* user_data, grpc_ssl_server_certificate_config** config) {
    State* state = static_cast<State*>(user_data);
    const std::lock_guard lock(state->mutex);
    if (state->next == nullptr) return GRPC_SSL_CERTIFICATE_CONFIG_RELOAD_UNCHANGED;
    *config = std::exchange(state->next, nullptr);  // gRPC owns it now
    return GRPC_SSL_CERTIFICATE_CONFIG_RELOAD_NEW;
  }

  // OpenSSL's certificate callback: called in each HTTPS handshake, from the listener's threads,
  // before the server's certificate and the client's verification are chosen.
  static int ServeIdentity(SSL* ssl, void* user_data) {
    State* state = static_cast<State*>(user_data);
    std::shared_ptr<const HttpsIdentity> identity;
    {
      const std::lock_guard lock(state->mutex);
      identity = state->https;
    }
    if (SSL_use_certificate(ssl, identity->leaf.get()) != 1 ||
        SSL_use_PrivateKey(ssl, identity->key.get()) != 1 ||
        SSL_set1_chain(ssl, identity->chain) != 1) {
      return 0;
    }
    if (identity->client_ca == nullptr) return 1;
    SSL_set_client_CA_list(ssl, SSL_dup_CA_list(identity->ca_names));
    return SSL_set1_verify_cert_store(ssl, identity->client_ca) == 1 ? 1 : 0;
  }
};

TlsCredentials::TlsCredentials(const TlsFiles& files) : state_(std::make_unique<State>()) {
  const Pem pem = ReadTlsFiles(files);
  state_->client_ca = !pem.client_ca.empty();
  state_->next = CertificateConfig(pem);
  state_->description = pem.description;
  state_->https = pem.https;
  grpc_ssl_server_credentials_options* options =
      grpc_ssl_server_credentials_create_options_using_config_fetcher(
          state_->client_ca ? GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY
                            : GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE,
          &State::Fetch, state_.get());
  grpc_server_credentials* credentials = grpc_ssl_server_credentials_create_with_options(options);
  if (credentials == nullptr) throw std::runtime_error("gRPC refused the TLS credentials");
  credentials_ = std::make_shared<CoreServerCredentials>(credentials);
}

TlsCredentials::~TlsCredentials() = default;  // credentials_ first, then state_

std::string TlsCredentials::Reload(const TlsFiles& files) {
  const Pem pem = ReadTlsFiles(files);
  if (pem.client_ca.empty() == state_->client_ca) {
    throw std::runtime_error(
        "--tls-client-ca can only be turned on or off by a restart (the certificate in use is "
        "kept)");
  }
  grpc_ssl_server_certificate_config* config = CertificateConfig(pem);
  const std::lock_guard lock(state_->mutex);
  if (state_->next != nullptr) grpc_ssl_server_certificate_config_destroy(state_->next);
  state_->next = config;
  state_->description = pem.description;
  state_->https = pem.https;
  return pem.description;
}

std::string TlsCredentials::Describe() const {
  const std::lock_guard lock(state_->mutex);
  return state_->description;
}

bool TlsCredentials::SetUpHttps(SSL_CTX& ctx) const {
  if (SSL_CTX_set_min_proto_version(&ctx, TLS1_2_VERSION) != 1) return false;
  SSL_CTX_set_options(&ctx, SSL_OP_NO_RENEGOTIATION | SSL_OP_NO_COMPRESSION);
  if (state_->client_ca) {
    SSL_CTX_set_verify(&ctx, SSL_VERIFY_PEER | SSL_VERIFY_FAIL_IF_NO_PEER_CERT, nullptr);
  }
  SSL_CTX_set_cert_cb(&ctx, &State::ServeIdentity, state_.get());
  return true;
}

bool IsLoopback(const std::string& address) {
  const size_t colon = address.rfind(':');
  std::string host = colon == std::string::npos ? address : address.substr(0, colon);
  if (host.size() > 2 && host.front() == '[' && host.back() == ']') {
    host = host.substr(1, host.size() - 2);
  }
  return host == "localhost" || host == "::1" || host.rfind("127.", 0) == 0 ||
         host.rfind("unix:", 0) == 0 || address.rfind("unix:", 0) == 0;
}

}  // namespace forestmap::server
