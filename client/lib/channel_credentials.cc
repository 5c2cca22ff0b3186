// ChannelCredentialsFor (client/lib/forestmap_client.h): plaintext or TLS from PEM files.

#include <grpcpp/security/credentials.h>

#include <fstream>
#include <sstream>
#include <stdexcept>

#include "client/lib/forestmap_client.h"

namespace forestmap::client {
namespace {

std::string ReadPem(const std::string& path, const char* what) {
  std::ifstream file(path, std::ios::binary);
  if (!file) throw std::runtime_error(std::string("cannot read ") + what + " " + path);
  std::ostringstream text;
  text << file.rdbuf();
  if (text.str().find("-----BEGIN ") == std::string::npos) {
    throw std::runtime_error(std::string(what) + " " + path + " is not a PEM file");
  }
  return text.str();
}

}  // namespace

std::shared_ptr<grpc::ChannelCredentials> ChannelCredentialsFor(const ClientOptions& options) {
  if (!options.tls && options.tls_ca.empty()) return grpc::InsecureChannelCredentials();
  grpc::SslCredentialsOptions ssl;
  if (!options.tls_ca.empty()) ssl.pem_root_certs = ReadPem(options.tls_ca, "--tls-ca");
  if (!options.tls_cert.empty()) {
    ssl.pem_cert_chain = ReadPem(options.tls_cert, "--tls-cert");
    ssl.pem_private_key = ReadPem(options.tls_key, "--tls-key");
  }
  return grpc::SslCredentials(ssl);
}

}  // namespace forestmap::client
