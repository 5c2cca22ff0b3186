// MapStore::PruneVersions: the newest versions stay readable and restorable, older ones are gone
// with the rows only they held; the current trees do not change. On every backend.

#include <gtest/gtest.h>

#include "tests/storage/store_backends.h"

namespace forestmap::storage {
namespace {

std::vector<TreeRecord> Trees(int count, double offset) {
  std::vector<TreeRecord> trees(count);
  for (int i = 0; i < count; ++i) {
    trees[i].x = offset + 3.0 * i;
    trees[i].y = 1.0 * i;
  }
  return trees;
}

class PruneTest : public ::testing::TestWithParam<Backend> {};
INSTANTIATE_TEST_SUITE_P(Backends, PruneTest, kAllBackends, BackendName);

TEST_P(PruneTest, KeepsTheNewestVersionsAndDropsTheRowsOnlyOlderOnesHeld) {
  TestStore test_store(GetParam());
  MapStore& store = *test_store;
  store.CreateMap("plot", "", "");
  for (int upload = 0; upload < 8; ++upload) {  // eight replace uploads: versions 2..9
    store.WriteTrees("plot", Trees(100, 1000.0 * upload), WriteMode::kReplace);
  }
  const MapSnapshot current = store.ReadMap("plot");
  const MapSnapshot kept = store.ReadMapVersion("plot", 8);
  ASSERT_EQ(current.info.version, 9);

  const PruneResult result = store.PruneVersions("plot", 2);
  EXPECT_EQ(result.info.version, 9);
  EXPECT_EQ(result.versions_removed, 7);     // 1..7
  EXPECT_EQ(result.tree_rows_removed, 600);  // the trees of versions 2..7
  EXPECT_EQ(store.ReadMap("plot").trees, current.trees);
  EXPECT_EQ(store.ReadMapVersion("plot", 8).trees, kept.trees);
  EXPECT_EQ(store.ListVersions("plot", 0).size(), 2u);
  for (int64_t gone : {1, 5, 7}) {
    try {
      store.ReadMapVersion("plot", gone);
      ADD_FAILURE() << "version " << gone << " still readable";
    } catch (const StorageError& e) {
      EXPECT_EQ(e.code(), StorageError::Code::kNotFound);
    }
    EXPECT_THROW(store.RestoreVersion("plot", gone), StorageError);
  }
  EXPECT_EQ(store.RestoreVersion("plot", 8).tree_count, 100);  // a kept version restores
  EXPECT_EQ(store.TreesInBox("plot", {6000, -1, 6400, 200}).size(), 100u);  // v8 trees, by index

  EXPECT_EQ(store.PruneVersions("plot", 100).versions_removed, 0);
  try {
    store.PruneVersions("plot", 0);
    ADD_FAILURE() << "keep 0 accepted";
  } catch (const StorageError& e) {
    EXPECT_EQ(e.code(), StorageError::Code::kInvalidArgument);
  }
}

}  // namespace
}  // namespace forestmap::storage
