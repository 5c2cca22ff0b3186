#include "server/ops/tls.h"

#include <grpcpp/security/server_credentials.h>

#include <fstream>
#include <sstream>
#include <stdexcept>

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

}  // namespace

std::shared_ptr<grpc::ServerCredentials> TlsServerCredentials(const TlsFiles& files) {
  if (files.cert.empty() || files.key.empty()) {
    throw std::runtime_error("TLS needs both --tls-cert and --tls-key");
  }
  grpc::SslServerCredentialsOptions options(
      files.client_ca.empty() ? GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE
                              : GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY);
  options.pem_key_cert_pairs.push_back(
      {ReadPem(files.key, "--tls-key"), ReadPem(files.cert, "--tls-cert")});
  if (!files.client_ca.empty())
    options.pem_root_certs = ReadPem(files.client_ca, "--tls-client-ca");
  return grpc::SslServerCredentials(options);
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
