#include "server/app/map_index_cache.h"

#include <gtest/gtest.h>

#include <chrono>
#include <condition_variable>
#include <functional>
#include <future>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <thread>

#include "server/app/errors.h"
#include "storage/sqlite/store.h"
#include "storage/staged_writes.h"
#include "tests/server/gated_store.h"

namespace forestmap::server {
namespace {

std::vector<storage::TreeRecord> Trees(int count, double offset = 0) {
  std::vector<storage::TreeRecord> trees(count);
  for (int i = 0; i < count; ++i) {
    trees[i].x = offset + 3.0 * i;
    trees[i].y = offset + 1.5 * i;
    if (i % 2 == 0) trees[i].dbh = 0.2;
  }
  return trees;
}

class MapIndexCacheTest : public ::testing::Test {
 protected:
  void AddMap(const std::string& name, int trees) {
    store_.CreateMap(name, "", "");
    if (trees > 0) store_.WriteTrees(name, Trees(trees), storage::WriteMode::kAppend);
  }

  storage::SqliteMapStore store_{":memory:"};
  GatedStore gated_{store_};
};

// A tree at x = 1e308 (stored before validation checked ranges) took the process
// down in the index build; now the map answers an error naming it, once per version.
TEST_F(MapIndexCacheTest, MapThatCannotBeIndexedIsAnErrorOfThatMapOnly) {
  AddMap("plot", 10);
  AddMap("far", 3);
  std::vector<storage::TreeRecord> far(1);
  far[0].x = 1e308;
  store_.WriteTrees("far", far, storage::WriteMode::kAppend);
  MapIndexCache cache(store_);
  for (int attempt = 0; attempt < 3; ++attempt) {
    try {
      cache.Get("far");
      ADD_FAILURE() << "no error";
    } catch (const PreconditionError& e) {
      EXPECT_NE(std::string(e.what()).find("map \"far\" (version 3) cannot be indexed"),
                std::string::npos)
          << e.what();
    }
  }
  EXPECT_EQ(cache.stats().builds, 1);  // not rebuilt for the same version
  EXPECT_EQ(cache.Get("plot").index->size(), 10u);
  // A new version of the map (the far tree replaced) is indexed again.
  store_.WriteTrees("far", Trees(4), storage::WriteMode::kReplace);
  EXPECT_EQ(cache.Get("far").index->size(), 4u);
}

TEST_F(MapIndexCacheTest, BuildsOncePerVersionAndRebuildsAfterAWrite) {
  AddMap("plot", 10);
  MapIndexCache cache(store_);
  const MapIndexCache::Entry first = cache.Get("plot");
  EXPECT_EQ(first.version, store_.GetMap("plot").version);
  ASSERT_EQ(first.index->size(), 10u);
  EXPECT_TRUE(std::isnan(first.index->trees()[0].position.z()));  // 2-D trees: z unknown
  const MapIndexCache::Entry again = cache.Get("plot");
  EXPECT_EQ(again.index, first.index);  // the same index object, shared
  EXPECT_EQ(cache.stats().builds, 1);
  EXPECT_EQ(cache.stats().hits, 1);

  store_.WriteTrees("plot", Trees(5, 1000), storage::WriteMode::kAppend);
  const MapIndexCache::Entry rebuilt = cache.Get("plot");
  EXPECT_EQ(rebuilt.version, first.version + 1);
  EXPECT_EQ(rebuilt.index->size(), 15u);
  EXPECT_NE(rebuilt.index, first.index);
  EXPECT_EQ(cache.stats().builds, 2);
  EXPECT_EQ(first.index->size(), 10u);  // a holder of the old index keeps a valid index
}

TEST_F(MapIndexCacheTest, UnknownOrDeletedMapIsNotFoundAndEvicted) {
  AddMap("plot", 4);
  MapIndexCache cache(store_);
  cache.Get("plot");
  EXPECT_EQ(cache.size(), 1u);
  store_.DeleteMap("plot");
  try {
    cache.Get("plot");
    FAIL() << "expected NOT_FOUND";
  } catch (const storage::StorageError& e) {
    EXPECT_EQ(e.code(), storage::StorageError::Code::kNotFound);
  }
  EXPECT_EQ(cache.size(), 0u);
}

TEST_F(MapIndexCacheTest, EmptyMapIsAPreconditionError) {
  AddMap("empty", 0);
  MapIndexCache cache(store_);
  try {
    cache.Get("empty");
    FAIL() << "expected FAILED_PRECONDITION";
  } catch (const PreconditionError& e) {
    EXPECT_NE(std::string(e.what()).find("\"empty\" has no confirmed trees"), std::string::npos);
  }
}

TEST_F(MapIndexCacheTest, EvictForcesARebuild) {
  AddMap("plot", 4);
  MapIndexCache cache(store_);
  const auto first = cache.Get("plot").index;
  cache.Evict("plot");
  EXPECT_NE(cache.Get("plot").index, first);
  EXPECT_EQ(cache.stats().builds, 2);
}

TEST_F(MapIndexCacheTest, KeepsAtMostMaxEntriesMaps) {
  for (const char* name : {"a", "b", "c"}) AddMap(name, 3);
  MapIndexCacheOptions options;
  options.max_entries = 2;
  MapIndexCache cache(store_, options);
  cache.Get("a");
  cache.Get("b");
  cache.Get("a");  // b is now the least recently used
  cache.Get("c");
  EXPECT_EQ(cache.size(), 2u);
  cache.Get("a");
  EXPECT_EQ(cache.stats().builds, 3);  // a stayed
  cache.Get("b");
  EXPECT_EQ(cache.stats().builds, 4);  // b had been dropped
}

TEST_F(MapIndexCacheTest, ConcurrentCallersShareOneBuildAndOtherMapsAreNotBlocked) {
  AddMap("slow", 20);
  AddMap("other", 5);
  MapIndexCache cache(gated_);
  gated_.Close("slow");
  constexpr int kCallers = 4;
  std::vector<std::future<MapIndexCache::Entry>> calls;
  calls.push_back(std::async(std::launch::async, [&] { return cache.Get("slow"); }));
  ASSERT_TRUE(gated_.WaitForReads("slow", 1));
  for (int i = 1; i < kCallers; ++i) {
    calls.push_back(std::async(std::launch::async, [&] { return cache.Get("slow"); }));
  }
  ASSERT_TRUE(Eventually([&] { return cache.stats().waits == kCallers - 1; }));
  // While "slow" is being built, another map is served.
  EXPECT_EQ(cache.Get("other").index->size(), 5u);
  gated_.Open();
  const MapIndexCache::Entry first = calls[0].get();
  for (int i = 1; i < kCallers; ++i) EXPECT_EQ(calls[i].get().index, first.index);
  EXPECT_EQ(first.index->size(), 20u);
  EXPECT_EQ(gated_.reads("slow"), 1);
  EXPECT_EQ(cache.stats().builds, 2);  // one for "slow", one for "other"
}

TEST_F(MapIndexCacheTest, WaitersGetTheErrorOfAFailedBuild) {
  AddMap("doomed", 5);
  MapIndexCache cache(gated_);
  gated_.Close("doomed");
  auto builder = std::async(std::launch::async, [&] { return cache.Get("doomed"); });
  ASSERT_TRUE(gated_.WaitForReads("doomed", 1));
  auto waiter = std::async(std::launch::async, [&] { return cache.Get("doomed"); });
  ASSERT_TRUE(Eventually([&] { return cache.stats().waits == 1; }));
  store_.DeleteMap("doomed");  // the snapshot read behind the gate now fails
  gated_.Open();
  EXPECT_THROW(builder.get(), storage::StorageError);
  EXPECT_THROW(waiter.get(), storage::StorageError);
  // The failed build left no stale state: a new map of that name gets a fresh build.
  AddMap("doomed", 7);
  EXPECT_EQ(cache.Get("doomed").index->size(), 7u);
}

}  // namespace
}  // namespace forestmap::server

namespace forestmap::server {
namespace {

// The survey boundary stored with a map is what its index says the map covers, instead of the
// area derived from the trees: ground far from any tree but inside the boundary counts as mapped
// (a drone's tree there that the map lacks is evidence against a pose), ground outside it does
// not; a later upload without a boundary keeps it, one that removes it brings the derived back.
TEST_F(MapIndexCacheTest, TheIndexCoversTheStoredBoundary) {
  AddMap("plot", 40);  // trees along a line: their own coverage is little more than their discs
  MapIndexCache cache(store_);
  const MapIndexCache::Entry derived = cache.Get("plot");
  EXPECT_TRUE(derived.index->coverage_derived());
  EXPECT_LT(derived.index->coverage_area(), 1000.0);

  storage::BoundaryPolygon square;
  square.outer = {{-50, -50}, {200, -50}, {200, 150}, {-50, 150}};
  const auto upload = [&](std::optional<storage::Boundary> boundary) {
    storage::UploadPlan plan;
    plan.boundary = std::move(boundary);
    auto writing = store_.BeginUpload("plot", plan);
    writing->Commit();
  };
  upload(storage::Boundary{square});
  const MapIndexCache::Entry bounded = cache.Get("plot");
  EXPECT_EQ(bounded.version, derived.version + 1);  // the boundary alone made a version
  EXPECT_FALSE(bounded.index->coverage_derived());
  ASSERT_EQ(bounded.index->coverage().size(), 1u);
  EXPECT_EQ(bounded.index->coverage()[0].outer.size(), 4u);
  EXPECT_EQ(bounded.index->coverage()[0].outer[2], Eigen::Vector2d(200, 150));
  EXPECT_NEAR(bounded.index->coverage_area(), 250.0 * 200.0, 250.0 * 200.0 * 0.01);

  store_.WriteTrees("plot", Trees(2, 10), storage::WriteMode::kAppend);  // keeps the boundary
  EXPECT_FALSE(cache.Get("plot").index->coverage_derived());
  upload(storage::Boundary{});  // removes it
  EXPECT_TRUE(cache.Get("plot").index->coverage_derived());
}

}  // namespace
}  // namespace forestmap::server
