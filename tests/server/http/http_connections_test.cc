// One client cannot hold every worker of the web port: at most kConnectionsPerClient connections
// of one remote address are served at a time, one more is answered 503 at once, and other
// clients are answered meanwhile. Loopback addresses stand for the clients: 127.0.0.2 opens
// connections that send nothing, 127.0.0.1 asks as usual.

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <string>
#include <thread>
#include <vector>

#include "server/app/recent_answers.h"
#include "server/http/http_listen.h"
#include "server/http/http_page.h"
#include "storage/sqlite/store.h"
#include "tests/server/http/closed_by_server.h"
#include "tests/server/http_get.h"

namespace forestmap::server {
namespace {

using Clock = std::chrono::steady_clock;
constexpr const char* kOther = "127.0.0.2";  // the client that holds connections
// Well under the 2 s read timeout, after which the held connections are closed anyway.
constexpr auto kPromptly = std::chrono::milliseconds(1000);
// How long a test waits for what must happen at all (a loaded machine is slow, not wrong).
constexpr auto kPatience = std::chrono::seconds(30);

// A TCP connection from `source` to 127.0.0.1:port that sends nothing yet; -1 on failure.
int ConnectFrom(const char* source, int port) {
  const int sock = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in from{};
  from.sin_family = AF_INET;
  inet_pton(AF_INET, source, &from.sin_addr);
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(static_cast<uint16_t>(port));
  to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (bind(sock, reinterpret_cast<sockaddr*>(&from), sizeof(from)) != 0 ||
      connect(sock, reinterpret_cast<sockaddr*>(&to), sizeof(to)) != 0) {
    close(sock);
    return -1;
  }
  return sock;
}

// What the server writes on `sock` until it closes it or `limit` passes.
std::string ReadUntilClosed(int sock, std::chrono::milliseconds limit) {
  std::string text;
  const Clock::time_point until = Clock::now() + limit;
  char buffer[4096];
  while (Clock::now() < until) {
    pollfd wait{sock, POLLIN, 0};
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(until - Clock::now());
    if (poll(&wait, 1, static_cast<int>(left.count()) + 1) <= 0) break;
    const ssize_t n = recv(sock, buffer, sizeof(buffer), 0);
    if (n <= 0) break;
    text.append(buffer, static_cast<size_t>(n));
  }
  return text;
}

// The status line of a GET of `path` sent from `source` (empty when nothing came back).
std::string StatusLineFrom(const char* source, int port, const std::string& path) {
  const int sock = ConnectFrom(source, port);
  if (sock < 0) return "";
  const std::string request =
      "GET " + path + " HTTP/1.1\r\nHost: forest\r\nConnection: close\r\n\r\n";
  send(sock, request.data(), request.size(), MSG_NOSIGNAL);
  const std::string answer = ReadUntilClosed(sock, kPromptly);
  close(sock);
  return answer.substr(0, answer.find("\r\n"));
}

class HttpConnectionsTest : public ::testing::Test {
 protected:
  HttpConnectionsTest() : store_(":memory:") {
    store_.CreateMap("plot-1", "", "");
    page_ = std::make_unique<HttpPage>(store_, answers_, "127.0.0.1:0", nullptr);
    port_ = std::stoi(page_->address().substr(page_->address().rfind(':') + 1));
  }
  ~HttpConnectionsTest() override {
    for (const int sock : held_) close(sock);
  }
  // Opens `count` silent connections from kOther.
  void Hold(int count) {
    for (int i = 0; i < count; ++i) {
      const int sock = ConnectFrom(kOther, port_);
      ASSERT_GE(sock, 0) << "cannot connect from " << kOther;
      held_.push_back(sock);
    }
  }

  storage::SqliteMapStore store_;
  RecentAnswers answers_;
  std::unique_ptr<HttpPage> page_;
  int port_ = 0;
  std::vector<int> held_;
};

TEST_F(HttpConnectionsTest, OneClientsConnectionsBeyondTheLimitAreAnswered503AtOnce) {
  Hold(kConnectionsPerClient);
  // The held connections are taken up as workers reach them: once all are, the same client's next
  // request is refused. A probe taken up before one of them gets a worker, and that connection is
  // refused instead; one the read timeout closes is opened again, so that the client keeps the
  // limit's worth open until a probe is refused.
  const Clock::time_point start = Clock::now();
  std::string refused;
  while (Clock::now() - start < kPatience) {
    for (int& sock : held_) {
      if (!test::ClosedByServer(sock)) continue;
      close(sock);
      sock = ConnectFrom(kOther, port_);
      ASSERT_GE(sock, 0) << "cannot connect from " << kOther;
    }
    refused = StatusLineFrom(kOther, port_, "/api/maps");
    if (refused.find(" 503 ") != std::string::npos) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_EQ(refused, "HTTP/1.1 503 Service Unavailable");
  // Another client is answered meanwhile.
  EXPECT_EQ(test::HttpGet("127.0.0.1", port_, "/api/maps").status, 200);
  EXPECT_EQ(StatusLineFrom("127.0.0.1", port_, "/api/maps"), "HTTP/1.1 200 OK");
  // Closing the held connections gives the client its places back.
  for (const int sock : held_) close(sock);
  held_.clear();
  std::string again;
  const Clock::time_point closed = Clock::now();
  while (Clock::now() - closed < kPromptly) {
    again = StatusLineFrom(kOther, port_, "/api/maps");
    if (again.find(" 200 ") != std::string::npos) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_EQ(again, "HTTP/1.1 200 OK");
}

// Silent connections of one client: the limit's worth are held (until the read timeout), every
// other one is answered 503 and closed at once instead of holding a worker, so 100 of them leave
// the other clients answered at once (the 64 workers would otherwise all be held for 2 s).
TEST_F(HttpConnectionsTest, HundredSilentConnectionsHoldOnlyTheLimitsWorth) {
  Hold(100);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const Clock::time_point start = Clock::now();
  EXPECT_EQ(test::HttpGet("127.0.0.1", port_, "/api/maps").status, 200);
  EXPECT_LT(Clock::now() - start, std::chrono::milliseconds(500));
  // Every connection of kOther, read together for 1.5 s: answered 503, or held (nothing yet).
  std::vector<pollfd> waits;
  for (const int sock : held_) waits.push_back({sock, POLLIN, 0});
  std::vector<std::string> answers(held_.size());
  std::vector<char> ended(held_.size(), 0);
  const Clock::time_point until = Clock::now() + std::chrono::milliseconds(1500);
  while (Clock::now() < until) {
    if (poll(waits.data(), waits.size(), 50) <= 0) continue;
    for (size_t i = 0; i < waits.size(); ++i) {
      if (ended[i] || (waits[i].revents & (POLLIN | POLLHUP | POLLERR)) == 0) continue;
      char buffer[4096];
      const ssize_t n = recv(held_[i], buffer, sizeof(buffer), MSG_DONTWAIT);
      if (n > 0) answers[i].append(buffer, static_cast<size_t>(n));
      if (n <= 0) ended[i] = 1, waits[i].events = 0;
    }
  }
  int refused = 0;
  int held = 0;
  for (size_t i = 0; i < held_.size(); ++i) {
    if (answers[i].starts_with("HTTP/1.1 503 Service Unavailable\r\n")) {
      ++refused;
      EXPECT_NE(answers[i].find("too many connections from this address"), std::string::npos);
    } else if (answers[i].empty() && !ended[i]) {
      ++held;
    }
  }
  std::printf("of 100 silent connections: %d refused, %d held\n", refused, held);
  EXPECT_EQ(refused, 100 - kConnectionsPerClient);
  EXPECT_LE(held, kConnectionsPerClient);
}

}  // namespace
}  // namespace forestmap::server
