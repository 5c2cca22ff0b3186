// forestmapd --http once showed every map to anyone, tokens or not. Now, once a token exists,
// every route needs one with read access on the map (Authorization: Bearer, or for a browser a
// cookie the page sets from /?token=; no other route takes a token in its address): checked
// route by route over HTTP, and in Debian's headless
// Chromium opening /?token=... and drawing the map's trees.

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "server/app/recent_answers.h"
#include "server/http/http_page.h"
#include "storage/sqlite/store.h"
#include "storage/token_store.h"
#include "tests/server/http_get.h"

namespace forestmap::server {
namespace {

namespace fs = std::filesystem;
using test::HttpGet;
using Json = nlohmann::json;
constexpr int kPlotTrees = 40;

std::vector<storage::TreeRecord> GridTrees(int count) {
  std::vector<storage::TreeRecord> trees(count);
  for (int i = 0; i < count; ++i) {
    trees[i].x = (i % 8) * 4.0;
    trees[i].y = (i / 8) * 4.0;
    trees[i].dbh = 0.3;
  }
  return trees;
}

class HttpPageAuthTest : public ::testing::Test {
 protected:
  HttpPageAuthTest()
      : dir_(fs::temp_directory_path() / ("http_page_auth_" + std::to_string(getpid()))),
        store_(":memory:") {
    fs::create_directories(dir_);
    tokens_ = std::make_unique<storage::TokenStore>((dir_ / "tokens.db").string());
    store_.CreateMap("plot-1", "", "");
    store_.WriteTrees("plot-1", GridTrees(kPlotTrees), storage::WriteMode::kAppend);
    store_.CreateMap("secret", "", "");
    page_ = std::make_unique<HttpPage>(store_, answers_, "127.0.0.1:0", tokens_.get());
    port_ = std::stoi(page_->address().substr(page_->address().rfind(':') + 1));
  }
  ~HttpPageAuthTest() override {
    page_.reset();
    fs::remove_all(dir_);
  }
  test::HttpAnswer Get(const std::string& path, const std::string& bearer = "",
                       const test::HttpHeaders& headers = {}) {
    return HttpGet("127.0.0.1", port_, path, bearer, headers);
  }

  fs::path dir_;
  storage::SqliteMapStore store_;
  RecentAnswers answers_;
  std::unique_ptr<storage::TokenStore> tokens_;
  std::unique_ptr<HttpPage> page_;
  int port_ = 0;
};

TEST_F(HttpPageAuthTest, OpenWithoutTokensClosedOnceOneExists) {
  EXPECT_EQ(Get("/api/maps").status, 200);  // no token exists yet: open, as before
  EXPECT_EQ(Json::parse(Get("/api/maps").body).size(), 2u);
  const std::string reader = tokens_->Create("plot-*", storage::Role::kRead).secret;
  const storage::NewToken revoked = tokens_->Create("*", storage::Role::kAdmin);
  tokens_->Revoke(revoked.record.id);

  for (const char* path : {"/", "/api/maps", "/api/maps/plot-1/trees", "/api/maps/plot-1/versions",
                           "/api/relocalizations"}) {
    EXPECT_EQ(Get(path).status, 401) << path;
    EXPECT_EQ(Get(path, reader + "x").status, 401) << path;
    EXPECT_EQ(Get(path, revoked.secret).status, 401) << path;
    EXPECT_EQ(Get(path, reader).status, 200) << path;
  }
  EXPECT_NE(Get("/api/maps").body.find("requires a token"), std::string::npos);
  // Only the maps the token can read.
  const Json maps = Json::parse(Get("/api/maps", reader).body);
  ASSERT_EQ(maps.size(), 1u);
  EXPECT_EQ(maps[0]["name"], "plot-1");
  EXPECT_EQ(Json::parse(Get("/api/maps/plot-1/trees", reader).body)["trees"].size(),
            static_cast<size_t>(kPlotTrees));
  const test::HttpAnswer denied = Get("/api/maps/secret/trees", reader);
  EXPECT_EQ(denied.status, 403);
  EXPECT_NE(denied.body.find("may not read map 'secret'"), std::string::npos) << denied.body;
  EXPECT_EQ(Get("/api/maps/secret/versions", reader).status, 403);
  // The browser's way: a first visit to /?token= moves the token into a cookie and reloads the
  // page without it in the address; the cookie then opens every route.
  const test::HttpAnswer first = Get("/?token=" + reader);
  EXPECT_EQ(first.status, 303);
  EXPECT_EQ(first.location, "/");
  EXPECT_EQ(first.set_cookie, "forestmap_token=" + reader + "; Path=/; HttpOnly; SameSite=Strict");
  EXPECT_EQ(Get("/?token=" + revoked.secret).status, 401);
  const std::string cookie = "theme=dark; forestmap_token=" + reader;
  EXPECT_EQ(Get("/", "", {{"Cookie", cookie}}).status, 200);
  EXPECT_EQ(Json::parse(Get("/api/maps", "", {{"Cookie", cookie}}).body).size(), 1u);
  EXPECT_EQ(Get("/api/maps", "", {{"Cookie", "forestmap_token=" + revoked.secret}}).status, 401);
  EXPECT_EQ(Get("/api/maps", "", {{"Cookie", "forestmap_tokenx=" + reader}}).status, 401);
}

// Only the token that was checked becomes the cookie: one sent in the header opens the page, and
// ?token= beside it (anything, even a header of its own: %0d%0a) sets nothing. A first visit's
// ?token= wins over an older cookie (a revoked token's), so that a new token can be opened.
TEST_F(HttpPageAuthTest, TheFirstVisitCookieIsTheCheckedToken) {
  const std::string reader = tokens_->Create("plot-*", storage::Role::kRead).secret;
  const storage::NewToken revoked = tokens_->Create("*", storage::Role::kAdmin);
  tokens_->Revoke(revoked.record.id);
  const test::HttpAnswer forged = Get("/?token=x%0d%0aSet-Cookie:%20a=b", reader);
  EXPECT_EQ(forged.status, 303);
  EXPECT_EQ(forged.location, "/");
  EXPECT_EQ(forged.set_cookie, "");
  const test::HttpAnswer renewed =
      Get("/?token=" + reader, "", {{"Cookie", "forestmap_token=" + revoked.secret}});
  EXPECT_EQ(renewed.status, 303);
  EXPECT_EQ(renewed.set_cookie,
            "forestmap_token=" + reader + "; Path=/; HttpOnly; SameSite=Strict");
  // Unknown paths answer 404 once the caller is known (401 before: nothing to probe).
  EXPECT_EQ(Get("/api/nothing").status, 401);
  EXPECT_EQ(Get("/api/nothing", reader).status, 404);
  EXPECT_EQ(Get("/api/maps/plot-1/nothing", reader).status, 404);
}

// A token in an address ends up in logs, proxies and browser histories: only the page's first
// visit takes one there. Every other route, API and OGC alike, refuses ?token= with 400 and says
// what to send instead, whatever else the request carries and whether tokens are in force or not.
TEST_F(HttpPageAuthTest, ApiRoutesRefuseATokenInTheAddress) {
  const std::vector<std::string> routes = {
      "/api/maps", "/api/maps/plot-1/trees", "/api/maps/plot-1/versions",    "/api/relocalizations",
      "/ogc",      "/ogc/collections",       "/ogc/collections/plot-1/items"};
  for (const std::string& path : routes) {
    const test::HttpAnswer open = Get(path + "?token=fmt_x");
    EXPECT_EQ(open.status, 400) << path << " (no token exists yet)";
  }
  const std::string reader = tokens_->Create("plot-*", storage::Role::kRead).secret;
  for (const std::string& path : routes) {
    const test::HttpAnswer in_address = Get(path + "?token=" + reader);
    EXPECT_EQ(in_address.status, 400) << path;
    EXPECT_NE(in_address.body.find("Authorization: Bearer"), std::string::npos)
        << path << ": " << in_address.body;
    EXPECT_EQ(
        Get(path + (path.find('?') == std::string::npos ? "?" : "&") + "token=" + reader, reader)
            .status,
        400)
        << path << " (with the header too)";
    EXPECT_EQ(Get(path, reader).status, 200) << path;
    EXPECT_EQ(Get(path, "", {{"Cookie", "forestmap_token=" + reader}}).status, 200) << path;
  }
  // The page's first visit still moves the token into its cookie.
  EXPECT_EQ(Get("/?token=" + reader).status, 303);
}

TEST_F(HttpPageAuthTest, TheBearerSchemeIsReadInAnyCase) {
  const std::string reader = tokens_->Create("plot-*", storage::Role::kRead).secret;
  for (const char* scheme : {"Bearer", "bearer", "BEARER"}) {
    const test::HttpAnswer answer =
        Get("/api/maps", "", {{"Authorization", std::string(scheme) + " " + reader}});
    EXPECT_EQ(answer.status, 200) << scheme;
  }
}

TEST_F(HttpPageAuthTest, ChromiumDrawsTheMapWithATokenInTheUrl) {
  const std::string reader = tokens_->Create("plot-*", storage::Role::kRead).secret;
  const std::string command =
      "chromium --headless --no-sandbox --disable-gpu --disable-quic --no-first-run "
      "--disable-background-networking --disable-component-update --disable-sync "
      "--window-size=1100,800 --virtual-time-budget=10000 --user-data-dir='" +
      (dir_ / "profile").string() + "' --dump-dom 'http://" + page_->address() +
      "/?token=" + reader + "#map=plot-1' 2>/dev/null";
  FILE* pipe = popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string dom;
  char buffer[4096];
  while (std::fgets(buffer, sizeof buffer, pipe)) dom += buffer;
  pclose(pipe);
  EXPECT_NE(dom.find("data-drawn=\"" + std::to_string(kPlotTrees) + "\""), std::string::npos)
      << dom.substr(0, 2000);
}

}  // namespace
}  // namespace forestmap::server
