#include "tests/server/http_get.h"

#include <httplib.h>
#include <signal.h>
#include <sys/socket.h>

namespace forestmap::test {
namespace {

HttpAnswer Get(httplib::ClientImpl& client, const std::string& path, const std::string& bearer,
               const HttpHeaders& headers) {
  // cpp-httplib waits for a readable socket with its timeouts, then reads it blocking: OpenSSL
  // may then wait for more of a record. The socket's own timeouts bound every read and write.
  client.set_socket_options([](int sock) {
    const timeval limit{20, 0};
    setsockopt(sock, SOL_SOCKET, SO_RCVTIMEO, &limit, sizeof limit);
    setsockopt(sock, SOL_SOCKET, SO_SNDTIMEO, &limit, sizeof limit);
  });
  httplib::Headers sent(headers.begin(), headers.end());
  if (!bearer.empty()) sent.emplace("Authorization", "Bearer " + bearer);
  const httplib::Result result = client.Get(path.c_str(), sent);
  HttpAnswer answer;
  if (!result) {
    answer.error = httplib::to_string(result.error());
    return answer;
  }
  answer.ok = true;
  answer.status = result->status;
  answer.content_type = result->get_header_value("Content-Type");
  answer.transfer_encoding = result->get_header_value("Transfer-Encoding");
  answer.location = result->get_header_value("Location");
  answer.set_cookie = result->get_header_value("Set-Cookie");
  answer.body = result->body;
  return answer;
}

}  // namespace

HttpAnswer HttpGet(const std::string& host, int port, const std::string& path,
                   const std::string& bearer, const HttpHeaders& headers) {
  httplib::ClientImpl client(host, port);
  return Get(client, path, bearer, headers);
}

HttpAnswer HttpsGet(const std::string& host, int port, const std::string& path,
                    const TlsClientFiles& tls, const std::string& bearer,
                    const HttpHeaders& headers) {
  // OpenSSL writes to the socket with write(): a server that closed it (a refused handshake)
  // would kill the test with SIGPIPE instead of failing the request.
  signal(SIGPIPE, SIG_IGN);
  httplib::SSLClient client(host, port, tls.cert, tls.key);
  client.set_ca_cert_path(tls.ca.c_str());
  client.enable_server_certificate_verification(true);
  client.set_connection_timeout(5);
  client.set_read_timeout(10);
  return Get(client, path, bearer, headers);
}

}  // namespace forestmap::test
