#pragma once
// TLS for forestmapd (--tls-cert, --tls-key, --tls-client-ca): gRPC server credentials from PEM
// files.

#include <grpcpp/security/server_credentials.h>

#include <memory>
#include <string>

namespace forestmap::server {

struct TlsFiles {
  std::string cert;       // PEM certificate chain of the server
  std::string key;        // PEM private key of `cert`
  std::string client_ca;  // PEM CA bundle; when set, clients must present a certificate it signed
};

// Reads the files and builds SSL server credentials. Throws std::runtime_error naming a file
// that cannot be read or is not PEM, or when only one of cert / key is given.
std::shared_ptr<grpc::ServerCredentials> TlsServerCredentials(const TlsFiles& files);

// True for a listen address that only loopback clients can reach (127.x, ::1, localhost).
bool IsLoopback(const std::string& address);

}  // namespace forestmap::server
