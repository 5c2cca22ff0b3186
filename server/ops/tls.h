#pragma once
// TLS for forestmapd (--tls-cert, --tls-key, --tls-client-ca): gRPC server credentials from PEM
// files, and the same certificate for its HTTPS listeners (--http, --metrics with --metrics-tls),
// which Reload() reads again while the server runs (forestmapd's SIGHUP): connections made after
// it get the new certificate, open ones keep theirs.

#include <grpcpp/security/server_credentials.h>
#include <openssl/types.h>

#include <memory>
#include <string>

namespace forestmap::server {

struct TlsFiles {
  std::string cert;       // PEM certificate chain of the server
  std::string key;        // PEM private key of `cert`
  std::string client_ca;  // PEM CA bundle; when set, clients must present a certificate it signed
  bool any() const { return !cert.empty() || !key.empty() || !client_ca.empty(); }
};

// gRPC's SSL server credentials on a certificate config fetcher: gRPC asks it before each new
// handshake, and it answers with the files of the last successful Reload(). (The C++ API has no
// such credentials; the fetcher is gRPC's C API for reloading certificates without a restart.)
// Thread-safety: Reload may be called from any thread while the server handshakes.
class TlsCredentials {
 public:
  // Reads and checks the files. Throws std::runtime_error naming the flag and the file that
  // cannot be read or is not PEM, when only one of cert / key is given, or when the key does
  // not belong to the certificate.
  explicit TlsCredentials(const TlsFiles& files);
  ~TlsCredentials();
  TlsCredentials(const TlsCredentials&) = delete;
  TlsCredentials& operator=(const TlsCredentials&) = delete;

  // For ServerOptions.credentials. This object must outlive every server built with them.
  std::shared_ptr<grpc::ServerCredentials> credentials() const { return credentials_; }

  // Reads `files` (the same paths or new ones) and makes them the next handshakes' certificate.
  // Throws as the constructor, or when --tls-client-ca would be turned on or off (a restart),
  // keeping the current certificate. Returns a description of the new one: "CN=... (not after
  // 2027-01-01T00:00:00Z)".
  std::string Reload(const TlsFiles& files);

  // The description of the certificate in use, as Reload returns it.
  std::string Describe() const;

  // Sets up OpenSSL's context of an HTTPS listener (server/http/http_listen.h) to serve what gRPC
  // serves: each handshake gets the certificate chain and key of the last Reload (TLS 1.2 or
  // later, no renegotiation), and with --tls-client-ca a client must present a certificate
  // signed by it or the handshake fails. This object must outlive every listener set up with it.
  bool SetUpHttps(SSL_CTX& ctx) const;

 private:
  struct State;
  std::unique_ptr<State> state_;
  std::shared_ptr<grpc::ServerCredentials> credentials_;
};

// True for a listen address that only loopback clients can reach (127.x, ::1, localhost).
bool IsLoopback(const std::string& address);

}  // namespace forestmap::server
