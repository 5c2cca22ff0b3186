// forestmapd's web page used as a person uses it, in Debian's headless Chromium driven through
// the DevTools protocol (--remote-debugging-pipe: JSON messages on file descriptors 3 and 4, so
// no extra client library): a mouse click on a stem names that tree in the corner (its id, place,
// DBH and status), and a drone's relocalization made while the page is open appears in its
// answers table within seconds, without a reload.

#include <fcntl.h>
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "client/lib/forestmap_client.h"
#include "server/grpc/server.h"
#include "server/grpc/service.h"
#include "server/http/http_page.h"
#include "storage/sqlite/store.h"

namespace forestmap::server {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

// A headless Chromium and its DevTools pipe. Calls fail the test (throw) after 30 s without an
// answer.
class Browser {
 public:
  explicit Browser(const fs::path& profile) {
    int to_browser[2], from_browser[2];
    if (pipe(to_browser) != 0 || pipe(from_browser) != 0) throw std::runtime_error("pipe");
    pid_ = fork();
    if (pid_ < 0) throw std::runtime_error("fork");
    if (pid_ == 0) {
      dup2(to_browser[0], 3);
      dup2(from_browser[1], 4);
      const int null = open("/dev/null", O_WRONLY);
      dup2(null, 1);
      dup2(null, 2);
      for (int fd = 5; fd < 1024; ++fd) close(fd);
      const std::string data = "--user-data-dir=" + profile.string();
      execlp("chromium", "chromium", "--headless", "--no-sandbox", "--disable-gpu",
             "--disable-quic", "--no-first-run", "--disable-background-networking",
             "--disable-component-update", "--disable-sync", "--window-size=1100,800",
             "--remote-debugging-pipe", data.c_str(), "about:blank", static_cast<char*>(nullptr));
      _exit(127);
    }
    close(to_browser[0]);
    close(from_browser[1]);
    out_ = to_browser[1];
    in_ = from_browser[0];
  }
  ~Browser() {
    try {
      Call("Browser.close");
    } catch (const std::exception&) {
      kill(pid_, SIGKILL);
    }
    close(out_);
    close(in_);
    waitpid(pid_, nullptr, 0);
  }

  // The result of `method`; `session`: of an attached page.
  Json Call(const std::string& method, const Json& params = Json::object(),
            const std::string& session = "") {
    Json message = {{"id", ++next_id_}, {"method", method}, {"params", params}};
    if (!session.empty()) message["sessionId"] = session;
    const std::string text = message.dump() + '\0';
    if (write(out_, text.data(), text.size()) != static_cast<ssize_t>(text.size())) {
      throw std::runtime_error("cannot write to the browser");
    }
    while (true) {
      const Json answer = Json::parse(Next());
      if (answer.value("id", 0) != next_id_) continue;  // events
      if (answer.contains("error")) throw std::runtime_error(method + ": " + answer.dump());
      return answer["result"];
    }
  }

  // Opens `url` in a new page; returns its session.
  std::string Open(const std::string& url) {
    const std::string target = Call("Target.createTarget", {{"url", url}})["targetId"];
    return Call("Target.attachToTarget", {{"targetId", target}, {"flatten", true}})["sessionId"];
  }

  // The value of a JavaScript expression in the page.
  Json Evaluate(const std::string& session, const std::string& expression) {
    const Json result =
        Call("Runtime.evaluate", {{"expression", expression}, {"returnByValue", true}}, session);
    return result["result"].value("value", Json());
  }

  // Polls `expression` until it is true; false after `seconds`.
  bool WaitFor(const std::string& session, const std::string& expression, double seconds) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (std::chrono::steady_clock::now() < end) {
      if (Evaluate(session, expression) == true) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    return false;
  }

  // A left click at (x, y) CSS pixels of the page, as the mouse makes it.
  void Click(const std::string& session, double x, double y) {
    for (const char* type : {"mousePressed", "mouseReleased"}) {
      Call("Input.dispatchMouseEvent",
           {{"type", type}, {"x", x}, {"y", y}, {"button", "left"}, {"clickCount", 1}}, session);
    }
  }

 private:
  // The next NUL-terminated message.
  std::string Next() {
    while (true) {
      const size_t end = buffer_.find('\0');
      if (end != std::string::npos) {
        std::string message = buffer_.substr(0, end);
        buffer_.erase(0, end + 1);
        return message;
      }
      pollfd ready{in_, POLLIN, 0};
      if (poll(&ready, 1, 30'000) <= 0) throw std::runtime_error("the browser does not answer");
      char chunk[65536];
      const ssize_t got = read(in_, chunk, sizeof(chunk));
      if (got <= 0) throw std::runtime_error("the browser closed its pipe");
      buffer_.append(chunk, static_cast<size_t>(got));
    }
  }

  pid_t pid_ = -1;
  int out_ = -1, in_ = -1;
  int next_id_ = 0;
  std::string buffer_;
};

TEST(HttpPageBrowserTest, AClickNamesTheTreeAndDroneAnswersArriveLive) {
  // 400 trees scattered over 100 m x 100 m.
  std::mt19937 random(7);
  std::uniform_real_distribution<double> coordinate(0, 100), diameter(0.15, 0.5);
  std::vector<storage::TreeRecord> trees(400);
  for (size_t i = 0; i < trees.size(); ++i) {
    trees[i].id = static_cast<int64_t>(i + 1);
    trees[i].x = coordinate(random);
    trees[i].y = coordinate(random);
    trees[i].dbh = diameter(random);
  }
  storage::SqliteMapStore store(":memory:");
  store.CreateMap("plot", "", "");
  store.WriteTrees("plot", trees, storage::WriteMode::kReplace);
  ForestMapService service(store, {});
  ServerRunner runner("127.0.0.1:0", service);
  HttpPage page(store, service.recent_answers(), "127.0.0.1:0");
  const fs::path dir = fs::temp_directory_path() / ("http_browser_" + std::to_string(getpid()));
  fs::create_directories(dir);
  {
    Browser browser(dir / "profile");
    const std::string tab = browser.Open("http://" + page.address() + "/#map=plot");
    ASSERT_TRUE(browser.WaitFor(tab, "document.body.dataset.drawn === '400'", 20))
        << browser.Evaluate(tab, "document.body.outerHTML").dump().substr(0, 2000);

    // Click tree 123 where the page drew it.
    const storage::TreeRecord& tree = trees[122];
    const Json at =
        browser.Evaluate(tab, "(() => { const r = canvas.getBoundingClientRect(); const p = px(" +
                                  std::to_string(tree.x) + ", " + std::to_string(tree.y) +
                                  "); return [r.left + p[0], r.top + p[1]]; })()");
    ASSERT_TRUE(at.is_array()) << at;
    browser.Click(tab, at[0], at[1]);
    EXPECT_EQ(browser.Evaluate(tab, "document.body.dataset.identified"), "123");
    char expected[128];
    std::snprintf(expected, sizeof(expected), "tree 123: x %.2f, y %.2f, DBH %.1f cm, confirmed",
                  tree.x, tree.y, *tree.dbh * 100);
    EXPECT_EQ(browser.Evaluate(tab, "document.getElementById('info').textContent"), expected);
    // A click on empty ground names nothing new (the page's corner keeps the last tree).
    browser.Click(tab, 2, 2);
    EXPECT_EQ(browser.Evaluate(tab, "document.body.dataset.identified"), "123");

    // No answers yet; a drone's relocalization shows up while the page stays open.
    const std::string rows = "document.getElementById('answers').rows.length";
    EXPECT_EQ(browser.Evaluate(tab, rows), 1);  // the header row only
    std::vector<algorithms::DetectedTree> seen;
    for (const storage::TreeRecord& t : trees) {
      if (std::hypot(t.x - 50, t.y - 50) > 15) continue;
      algorithms::DetectedTree detected;
      detected.position = Eigen::Vector3d(t.x - 50, t.y - 50, 0);  // sensor at (50, 50)
      detected.dbh = *t.dbh;
      seen.push_back(detected);
    }
    client::ForestMapClient client(runner.address());
    const v1::RelocalizeResponse answer = client.Relocalize("plot", seen);
    EXPECT_TRUE(browser.WaitFor(
        tab,
        rows + " === 2 && document.getElementById('answers').rows[1].cells[0].textContent === "
               "'plot'",
        10))
        << browser.Evaluate(tab, "document.getElementById('answers').outerHTML") << "\n"
        << answer.DebugString();
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace forestmap::server
