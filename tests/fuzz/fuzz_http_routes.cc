// libFuzzer target for the HTTP routes of forestmapd: each input is the raw bytes a client sends
// on one connection (requests, keep-alive), parsed by cpp-httplib's own request parser
// (Server::process_request on a stream in memory: no socket) and routed twice:
//   - by the web page's reading of a request (server/http/http_route.h: route, map name, token
//     from the header, the page's ?token= or the cookie), whose results are checked against
//     the request;
//   - by the metrics port's routes (server/http/metrics_http.h) over a Metrics whose method
//     names come from the input too.
// Every answer written must be well-formed HTTP: a status line, then "Name: value" lines without
// a stray CR or LF (no header injected from the request), then the blank line. A sanitizer
// report, an exception out of a handler or a broken invariant is a crash.
#include <httplib.h>

#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <utility>

#include "server/http/http_route.h"
#include "server/http/metrics_http.h"
#include "server/ops/metrics.h"

namespace {

namespace fs = forestmap::server;

void Check(bool ok) {
  if (!ok) __builtin_trap();
}

// One connection's bytes in, the server's answers out.
class MemoryStream final : public httplib::Stream {
 public:
  explicit MemoryStream(std::string_view input) : input_(input) {}
  bool is_readable() const override { return true; }
  bool is_writable() const override { return true; }
  ssize_t read(char* ptr, size_t size) override {
    const size_t n = std::min(size, input_.size());
    std::memcpy(ptr, input_.data(), n);
    input_.remove_prefix(n);
    return static_cast<ssize_t>(n);
  }
  ssize_t write(const char* ptr, size_t size) override {
    output_.append(ptr, size);
    return static_cast<ssize_t>(size);
  }
  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    ip = "127.0.0.1";
    port = 40000;
  }
  void get_local_ip_and_port(std::string& ip, int& port) const override {
    ip = "127.0.0.1";
    port = 8080;
  }
  socket_t socket() const override { return -1; }
  bool done() const { return input_.empty(); }
  const std::string& output() const { return output_; }

 private:
  std::string_view input_;
  std::string output_;
};

void CheckAnswer(std::string_view answer);

// A server whose protected request processing is reachable without a socket.
class FuzzServer : public httplib::Server {
 public:
  // Serves the requests in `bytes` (at most 8), checking each answer.
  void Serve(std::string_view bytes) {
    MemoryStream stream(bytes);
    bool closed = false;
    size_t written = 0;
    for (int request = 0; request < 8 && !stream.done() && !closed; ++request) {
      const bool served =
          process_request(stream, /*close_connection=*/false, closed, [](httplib::Request&) {});
      CheckAnswer(std::string_view(stream.output()).substr(written));
      written = stream.output().size();
      if (!served) break;
    }
  }
};

bool IsNameChar(char c) {
  return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' ||
         c == '.' || c == '-';
}

// The page's reading of `request`, checked against the request itself.
void CheckPageRequest(const httplib::Request& request, const fs::PageRequest& read) {
  const std::string& path = request.path;
  switch (read.route) {
    case fs::PageRoute::kPage:
      Check(path == "/");
      break;
    case fs::PageRoute::kMaps:
      Check(path == "/api/maps");
      break;
    case fs::PageRoute::kRelocalizations:
      Check(path == "/api/relocalizations");
      break;
    case fs::PageRoute::kTrees:
    case fs::PageRoute::kDensity:
    case fs::PageRoute::kVersions:
    case fs::PageRoute::kBoundary: {
      Check(!read.map.empty());
      for (const char c : read.map) Check(IsNameChar(c));
      const char* what = read.route == fs::PageRoute::kTrees      ? "/trees"
                         : read.route == fs::PageRoute::kDensity  ? "/density"
                         : read.route == fs::PageRoute::kVersions ? "/versions"
                                                                  : "/boundary";
      Check(path == "/api/maps/" + read.map + what);
      break;
    }
    case fs::PageRoute::kNotFound:
      Check(read.map.empty());
      break;
  }
  Check(read.authorization == request.get_header_value("Authorization"));
  if (!read.authorization.empty()) {
    Check(read.token.empty() && !read.token_in_query);
  } else if (read.token_in_query) {
    Check(read.route == fs::PageRoute::kPage && !read.token.empty() &&
          read.token == request.get_param_value("token"));
  } else {
    Check(read.token == fs::CookieValue(request.get_header_value("Cookie"), fs::kTokenCookie));
  }
}

// One answer: a status line, header lines "Name: value", a blank line, then a body of its
// Content-Length (none for HEAD) or chunks.
void CheckAnswer(std::string_view answer) {
  if (answer.empty()) return;  // a connection closed without an answer
  const size_t head_end = answer.find("\r\n\r\n");
  Check(head_end != std::string_view::npos);
  std::string_view head = answer.substr(0, head_end + 2);
  const std::string_view body = answer.substr(head_end + 4);
  Check(head.starts_with("HTTP/1.1 ") && head.size() > 13 && head[12] == ' ');
  size_t length = 0;
  bool chunked = false;
  for (bool status_line = true; !head.empty(); status_line = false) {
    const size_t end = head.find("\r\n");
    const std::string_view line = head.substr(0, end);
    head.remove_prefix(end + 2);
    Check(line.find('\r') == std::string_view::npos && line.find('\n') == std::string_view::npos);
    if (status_line) continue;
    const size_t colon = line.find(": ");
    Check(colon != std::string_view::npos && colon > 0);
    const std::string_view name = line.substr(0, colon);
    for (const char c : name) Check(c > ' ' && c < 127 && c != ':');
    if (name == "Content-Length") length = std::stoul(std::string(line.substr(colon + 2)));
    if (name == "Transfer-Encoding") chunked = true;
  }
  Check(chunked || body.empty() || body.size() == length);
}

FuzzServer& PageServer() {
  static FuzzServer& server = *[] {
    auto* http = new FuzzServer;
    http->Get(R"([\s\S]*)", [](const httplib::Request& request, httplib::Response& response) {
      const fs::PageRequest read = fs::ReadPageRequest(request);
      CheckPageRequest(request, read);
      response.status = read.route == fs::PageRoute::kNotFound ? 404 : 200;
      if (read.token_in_query) {  // as the first visit's cookie: what the request carried
        response.set_header("Set-Cookie", std::string(fs::kTokenCookie) + "=" + read.token);
      }
      response.set_content(read.map, "text/plain");
    });
    return http;
  }();
  return server;
}

// The metrics port over the Metrics of the input being run (fresh for each input, so that an
// input always gives the same answers), counting the requests' paths as method names.
fs::Metrics* current_metrics = nullptr;

FuzzServer& MetricsServer() {
  static FuzzServer& server = *[] {
    auto* http = new FuzzServer;
    fs::AddMetricsRoutes(
        *http, [] { return current_metrics->Render(); },
        [] { return std::make_pair(false, std::string("starting \"\n")); });
    http->set_pre_routing_handler([](const httplib::Request& request, httplib::Response&) {
      current_metrics->RpcStarted(request.path, false);
      current_metrics->RpcFinished(request.path, false, grpc::StatusCode::UNIMPLEMENTED, 0.001);
      return httplib::Server::HandlerResponse::Unhandled;
    });
    return http;
  }();
  return server;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  PageServer().Serve(bytes);
  fs::Metrics metrics;
  current_metrics = &metrics;
  MetricsServer().Serve(bytes);
  current_metrics = nullptr;
  return 0;
}
