// A survey-sized map on the backends that hold one (SQLite on a file, PostgreSQL): a million
// trees through one write and one read, and the spatial index against brute force.
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "tests/storage/store_backends.h"
#include "tests/storage/store_test_util.h"

namespace forestmap::storage {
namespace {

// A survey-sized map goes through one write and one read whole, and the spatial index answers
// small boxes exactly (a query plan that scanned the map per block would make this crawl).
class LargeMapTest : public ::testing::TestWithParam<Backend> {};
INSTANTIATE_TEST_SUITE_P(Backends, LargeMapTest, kSharedBackends, BackendName);

TEST_P(LargeMapTest, MillionTreeMapWritesAndReadsBack) {
  TestStore test_store(GetParam());
  MapStore& store = *test_store;
  constexpr int64_t kTrees = 1'000'000;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> coordinate(0.0, 2000.0);  // m: a 4 km^2 forest
  std::vector<TreeRecord> trees(kTrees);
  for (int64_t i = 0; i < kTrees; ++i) {
    TreeRecord& tree = trees[static_cast<size_t>(i)];
    tree = Tree(i + 1, coordinate(rng), coordinate(rng));
    tree.dbh = 0.1 + static_cast<double>(i % 50) * 0.01;
  }
  store.CreateMap("big", "", "");
  const MapInfo info = store.WriteTrees("big", trees, WriteMode::kReplace);
  EXPECT_EQ(info.tree_count, kTrees);

  const MapSnapshot snapshot = store.ReadMap("big");
  EXPECT_EQ(snapshot.info.version, info.version);
  ASSERT_EQ(snapshot.trees.size(), trees.size());
  EXPECT_TRUE(snapshot.trees == trees);

  for (int query = 0; query < 50; ++query) {
    const double x = coordinate(rng), y = coordinate(rng);
    const Extent box{x, y, x + 15.0, y + 15.0};
    std::vector<int64_t> expected;
    for (const TreeRecord& tree : trees) {
      if (tree.x >= box.min_x && tree.x <= box.max_x && tree.y >= box.min_y &&
          tree.y <= box.max_y) {
        expected.push_back(*tree.id);
      }
    }
    std::vector<int64_t> found;
    for (const TreeRecord& tree : store.TreesInBox("big", box)) found.push_back(*tree.id);
    ASSERT_EQ(found, expected) << "box at " << x << ", " << y;
  }
}

}  // namespace
}  // namespace forestmap::storage
