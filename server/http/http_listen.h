#pragma once
// Binding forestmapd's HTTP listeners (--http, --metrics) the way its gRPC --listen binds: one
// port, one server. cpp-httplib sets SO_REUSEPORT on its sockets by default, which lets a second
// forestmapd bind a port already in use and silently take part of its connections; the sockets
// bound here only get SO_REUSEADDR (restart after TIME_WAIT), so a port in use is an error. Each
// listener has 64 workers and a 2 s read timeout, so idle or half-open connections cannot stall
// it. With an HttpsSetup it serves HTTPS only (cpp-httplib on OpenSSL), and a TLS handshake
// still running after 5 s is ended (server/http/handshake_deadline.h).

#include <openssl/types.h>

#include <atomic>
#include <functional>
#include <memory>
#include <string>
#include <thread>

namespace httplib {
class Server;
}  // namespace httplib

namespace forestmap::server {

class HandshakeDeadline;

// How a listener serves HTTPS: sets up OpenSSL's context of its connections (certificate, key,
// client verification: TlsCredentials::SetUpHttps), false when it cannot. Empty: plain HTTP.
using HttpsSetup = std::function<bool(SSL_CTX&)>;

// Binds `http` to `address` ("host:port" or "[v6]:port"; port 0: any free one) and returns the
// bound port. `flag` names the option in errors ("--http"). Throws std::runtime_error naming
// the flag, the address and the reason, e.g. "--http 127.0.0.1:8080: address already in use".
int BindHttpListener(httplib::Server& http, const std::string& flag, const std::string& address);

// "host:port" with the port replaced by `port` (for port 0), as BindHttpListener read it.
std::string BoundHttpAddress(const std::string& address, int port);

// An HTTP server bound with BindHttpListener and served on its own thread until destroyed.
class HttpListener {
 public:
  using Routes = std::function<void(httplib::Server&)>;

  // A server (HTTPS with `https`) with the routes `routes` adds, bound to `address`; throws as
  // BindHttpListener, or naming `flag` when `https` fails.
  HttpListener(const std::string& flag, const std::string& address, const HttpsSetup& https,
               const Routes& routes);
  ~HttpListener();  // stops serving and joins the thread
  HttpListener(const HttpListener&) = delete;
  HttpListener& operator=(const HttpListener&) = delete;

  int port() const { return port_; }
  const std::string& address() const { return address_; }  // host:port actually bound
  bool https() const { return deadline_ != nullptr; }
  std::string url() const { return (https() ? "https://" : "http://") + address_; }

 private:
  std::unique_ptr<HandshakeDeadline> deadline_;  // with HTTPS; outlives the server's handshakes
  std::unique_ptr<httplib::Server> http_;
  int port_ = 0;
  std::string address_;
  std::atomic<bool> stopped_{false};  // the listen loop has ended
  std::thread thread_;
};

}  // namespace forestmap::server
