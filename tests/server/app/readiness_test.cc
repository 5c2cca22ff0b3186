// Readiness (server/app/readiness.h) on a real SQLite store: the server is not ready until every
// preloaded map's index is built, a preloaded map written to is rebuilt without a query, and maps
// that cannot be indexed (no trees, not there) do not hold readiness back. (The database going
// away and coming back: tests/integration/daemon_faults_test.cc, with PostgreSQL.)

#include "server/app/readiness.h"

#include <gtest/gtest.h>

#include <map>
#include <mutex>
#include <string>

#include "storage/sqlite/store.h"
#include "tests/server/gated_store.h"

namespace forestmap::server {
namespace {

std::vector<storage::TreeRecord> SpreadTrees(int count) {
  std::vector<storage::TreeRecord> trees(count);
  for (int i = 0; i < count; ++i) {
    trees[i].x = 3.0 * i;
    trees[i].y = 1.7 * (i % 7);
  }
  return trees;
}

class ReadinessTest : public ::testing::Test {
 protected:
  ReadinessTest() {
    options_.interval = std::chrono::milliseconds(10);
    store_.CreateMap("forest", "", "");
    store_.WriteTrees("forest", SpreadTrees(50), storage::WriteMode::kAppend);
    store_.CreateMap("empty", "", "");
  }
  std::unique_ptr<Readiness> Start() {
    return std::make_unique<Readiness>(
        gated_, cache_, options_,
        [this](const std::string& name, bool serving, const std::string&) {
          std::lock_guard<std::mutex> lock(mutex_);
          published_[name] = serving;
        });
  }
  std::optional<bool> Published(const std::string& name) {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto found = published_.find(name);
    return found == published_.end() ? std::nullopt : std::optional<bool>(found->second);
  }

  storage::SqliteMapStore store_{":memory:"};
  GatedStore gated_{store_};
  MapIndexCache cache_{gated_};
  ReadinessOptions options_;
  std::mutex mutex_;
  std::map<std::string, bool> published_;
};

TEST_F(ReadinessTest, TheServerIsNotReadyUntilThePreloadedIndexIsBuilt) {
  options_.preload = {"forest"};
  gated_.Close("forest");  // the index build's snapshot read waits here
  const auto readiness = Start();
  ASSERT_TRUE(gated_.WaitForReads("forest", 1));
  EXPECT_FALSE(readiness->state().ready);
  EXPECT_EQ(Published(""), false);
  EXPECT_EQ(Published("map/forest"), std::nullopt);
  gated_.Open();
  ASSERT_TRUE(Eventually([&] { return readiness->state().ready; }));
  EXPECT_EQ(readiness->state().reason, "");
  EXPECT_TRUE(Eventually([&] { return Published("") == true; }));
  EXPECT_TRUE(Eventually([&] { return Published("map/forest") == true; }));
  EXPECT_EQ(cache_.stats().builds, 1);
  EXPECT_EQ(cache_.stats().hits, 0);  // warming is not a query
}

TEST_F(ReadinessTest, APreloadedMapThatWasWrittenToIsRebuiltWithoutAQuery) {
  options_.preload_all = true;
  const auto readiness = Start();
  ASSERT_TRUE(Eventually([&] { return readiness->state().ready; }));
  ASSERT_EQ(cache_.stats().builds, 1);
  store_.WriteTrees("forest", SpreadTrees(60), storage::WriteMode::kReplace);
  EXPECT_TRUE(Eventually([&] { return cache_.stats().builds == 2; }));
  EXPECT_EQ(cache_.Get("forest").version, store_.GetMap("forest").version);
  EXPECT_EQ(cache_.stats().builds, 2);  // the query found the index warm
}

TEST_F(ReadinessTest, MapsWithoutTreesOrMissingDoNotHoldReadinessBack) {
  options_.preload = {"empty", "no-such-map"};
  const auto readiness = Start();
  ASSERT_TRUE(Eventually([&] { return readiness->state().ready; }));
  EXPECT_TRUE(Eventually([&] { return Published("map/empty") == false; }));
  EXPECT_TRUE(Eventually([&] { return Published("map/no-such-map") == false; }));
  EXPECT_EQ(cache_.stats().builds, 0);
}

TEST_F(ReadinessTest, PreloadListsAreParsedAndEmptyNamesRefused) {
  ReadinessOptions options;
  ParsePreload("all", options);
  EXPECT_TRUE(options.preload_all);
  ParsePreload("a,b", options);
  EXPECT_FALSE(options.preload_all);
  EXPECT_EQ(options.preload, (std::vector<std::string>{"a", "b"}));
  EXPECT_THROW(ParsePreload("a,,b", options), std::invalid_argument);
  EXPECT_THROW(ParsePreload("", options), std::invalid_argument);
}

}  // namespace
}  // namespace forestmap::server
