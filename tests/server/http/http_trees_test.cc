// The web page's tree route (server/http/http_trees.h) and its listeners
// (server/http/http_listen.h): /api/maps/NAME/trees is streamed in chunks read page by page and
// holds every tree exactly, at the page boundaries too; --http and --metrics refuse a port in use
// (cpp-httplib's default SO_REUSEPORT let a second server share it) and malformed addresses, naming
// flag and address.

#include "server/http/http_trees.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "server/app/recent_answers.h"
#include "server/http/http_page.h"
#include "server/http/metrics_http.h"
#include "storage/sqlite/store.h"
#include "tests/server/http_get.h"

namespace forestmap::server {
namespace {

using Json = nlohmann::json;
using test::HttpGet;

constexpr int kCandidateEvery = 5;  // every 5th generated tree is a candidate
constexpr int kNoDbhEvery = 7;      // every 7th has no DBH

std::vector<storage::TreeRecord> RandomTrees(int count, uint32_t seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> metres(-5000.0, 5000.0);
  std::uniform_real_distribution<double> dbh(0.05, 0.9);
  std::vector<storage::TreeRecord> trees(count);
  for (int i = 0; i < count; ++i) {
    trees[i].x = metres(random);
    trees[i].y = metres(random);
    if (i % kNoDbhEvery != 0) trees[i].dbh = dbh(random);
    if (i % kCandidateEvery == 0) trees[i].status = storage::TreeStatus::kCandidate;
  }
  return trees;
}

int PortOf(const std::string& address) { return std::stoi(address.substr(address.rfind(':') + 1)); }

// Runs `body`, expects std::runtime_error and returns its message.
template <typename Body>
std::string ErrorOf(Body&& body) {
  try {
    body();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  ADD_FAILURE() << "no exception";
  return "";
}

class HttpTreesTest : public ::testing::Test {
 protected:
  storage::SqliteMapStore store_{":memory:"};
  RecentAnswers answers_;
  HttpPage page_{store_, answers_, "127.0.0.1:0"};
};

TEST_F(HttpTreesTest, StreamsEveryTreeExactlyAcrossPageBoundaries) {
  const std::vector<int> sizes = {0, 1, int{kHttpTreesPage}, int{kHttpTreesPage} + 1, 10'000};
  for (const int size : sizes) {
    const std::string name = "plot" + std::to_string(size);
    store_.CreateMap(name, "", "");
    const std::vector<storage::TreeRecord> truth = RandomTrees(size, 7u + size);
    if (size > 0) store_.WriteTrees(name, truth, storage::WriteMode::kReplace);

    const test::HttpAnswer answer =
        HttpGet("127.0.0.1", PortOf(page_.address()), "/api/maps/" + name + "/trees");
    ASSERT_TRUE(answer.ok);
    ASSERT_EQ(answer.status, 200) << answer.body;
    EXPECT_EQ(answer.content_type, "application/json");
    EXPECT_EQ(answer.transfer_encoding, "chunked");  // streamed, never one whole document
    const Json body = Json::parse(answer.body);
    EXPECT_EQ(body["map"]["name"], name);
    EXPECT_EQ(body["map"]["trees"], size);
    ASSERT_EQ(body["trees"].size(), truth.size()) << name;
    int64_t last_id = INT64_MIN;
    for (int i = 0; i < size; ++i) {
      const Json& tree = body["trees"][i];
      ASSERT_EQ(tree.size(), 5u);
      EXPECT_GT(tree[4].get<int64_t>(), last_id) << name << " tree " << i;  // ids, increasing
      last_id = tree[4].get<int64_t>();
      EXPECT_EQ(tree[0].get<double>(), truth[i].x) << name << " tree " << i;  // bit for bit
      EXPECT_EQ(tree[1].get<double>(), truth[i].y) << name << " tree " << i;
      if (truth[i].dbh) {
        EXPECT_EQ(tree[2].get<double>(), *truth[i].dbh) << name << " tree " << i;
      } else {
        EXPECT_TRUE(tree[2].is_null()) << name << " tree " << i;
      }
      EXPECT_EQ(tree[3].get<bool>(), truth[i].status == storage::TreeStatus::kConfirmed);
    }
    // ?bbox=: exactly the trees inside (edges included), also across page boundaries.
    const double x0 = -1000, y0 = -2000, x1 = 2500, y1 = 1500;
    const auto inside = std::count_if(truth.begin(), truth.end(), [&](const auto& t) {
      return t.x >= x0 && t.x <= x1 && t.y >= y0 && t.y <= y1;
    });
    const test::HttpAnswer boxed =
        HttpGet("127.0.0.1", PortOf(page_.address()),
                "/api/maps/" + name + "/trees?bbox=-1000,-2000,2500,1500");
    ASSERT_EQ(boxed.status, 200) << boxed.body;
    EXPECT_EQ(Json::parse(boxed.body)["trees"].size(), static_cast<size_t>(inside)) << name;
  }
  EXPECT_EQ(HttpGet("127.0.0.1", PortOf(page_.address()), "/api/maps/plot0/trees?bbox=1,2").status,
            400);
}

TEST_F(HttpTreesTest, UnknownMapIs404) {
  const test::HttpAnswer answer =
      HttpGet("127.0.0.1", PortOf(page_.address()), "/api/maps/nothing/trees");
  ASSERT_TRUE(answer.ok);
  EXPECT_EQ(answer.status, 404);
  EXPECT_NE(Json::parse(answer.body)["error"].get<std::string>().find("nothing"),
            std::string::npos);
}

TEST_F(HttpTreesTest, PortInUseIsRefusedNamingFlagAndAddress) {
  const std::string taken = page_.address();
  EXPECT_EQ(ErrorOf([&] { HttpPage second(store_, answers_, taken); }),
            "--http " + taken + ": address already in use");
  EXPECT_EQ(ErrorOf([&] {
              MetricsHttpServer metrics(
                  taken, [] { return std::string(); },
                  [] { return std::make_pair(true, std::string()); });
            }),
            "--metrics " + taken + ": address already in use");
  // The first page still answers alone.
  EXPECT_EQ(HttpGet("127.0.0.1", PortOf(taken), "/api/maps").status, 200);
}

TEST_F(HttpTreesTest, MalformedAddressesAreRefused) {
  for (const std::string address :
       {"localhost", "127.0.0.1:", "127.0.0.1:x", "127.0.0.1:70000", ":8080", "127.0.0.1:-1"}) {
    const std::string message = ErrorOf([&] { HttpPage bad(store_, answers_, address); });
    EXPECT_EQ(message.rfind("--http " + address + ": give host:port", 0), 0u) << message;
  }
  EXPECT_NE(ErrorOf([&] {
              HttpPage bad(store_, answers_, "no-such-host.invalid:8080");
            }).find("--http no-such-host.invalid:8080: cannot resolve the host"),
            std::string::npos);
}

}  // namespace
}  // namespace forestmap::server
