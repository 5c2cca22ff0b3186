#pragma once
// Binding forestmapd's HTTP listeners (--http, --metrics) the way its gRPC --listen binds: one
// port, one server. cpp-httplib sets SO_REUSEPORT on its sockets by default, which lets a second
// forestmapd bind a port already in use and silently take part of its connections; the sockets
// bound here only get SO_REUSEADDR (restart after TIME_WAIT), so a port in use is an error. Each
// listener has 64 workers and a 2 s read timeout, so idle or half-open connections cannot stall
// it, and serves at most kConnectionsPerClient connections of one remote address at a time: one
// more is answered 503 at once (over HTTPS, closed), so one client cannot hold all the workers.
// With an HttpsSetup it serves HTTPS only (cpp-httplib on OpenSSL), and a TLS handshake still
// running after 5 s is ended (server/http/handshake_deadline.h).

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
class ConnectionGate;

// Connections of one remote address (IP) an HTTP listener serves at a time.
inline constexpr int kConnectionsPerClient = 8;

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
  std::unique_ptr<httplib::Server> http_;        // the routes; serves what gate_ lets through
  std::unique_ptr<ConnectionGate> gate_;         // binds, accepts, limits connections per client
  int port_ = 0;
  std::string address_;
  std::atomic<bool> stopped_{false};  // the listen loop has ended
  std::thread thread_;
};

}  // namespace forestmap::server
