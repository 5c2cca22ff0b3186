// MapStore versions (shared maps) on every backend: every version readable, history, restore,
// the merge transaction (reads and writes in one transaction, all or nothing, stale checks).
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "tests/storage/store_backends.h"
#include "tests/storage/store_test_util.h"

namespace forestmap::storage {
namespace {

using Code = StorageError::Code;

TreeRecord Candidate(int64_t id, double x, double y, int64_t observations) {
  TreeRecord tree = Tree(id, x, y);
  tree.status = TreeStatus::kCandidate;
  tree.observations = observations;
  tree.position_sigma = 0.05;
  return tree;
}

class MapVersionsTest : public ::testing::TestWithParam<Backend> {
 protected:
  // Version 2 upload {1,2,3}; version 3 one candidate (id 4) with an observation of "drone-a".
  void SetUp() override {
    store_.CreateMap("m", "", "");
    store_.WriteTrees("m", {Tree(1, 0, 0), Tree(2, 10, 0), Tree(3, 0, 10)}, WriteMode::kAppend);
    store_.Merge("m", MergeNote{VersionKind::kObserve, "drone-a", std::nullopt},
                 [](MergeReader& reader) {
                   MapChanges changes;
                   const int64_t id = reader.NextFreeTreeId();
                   EXPECT_EQ(id, 4);
                   changes.put_trees.push_back(Candidate(id, 5, 5, 1));
                   changes.added_observations.push_back(Observation(id, "drone-a", 5, 5));
                   return changes;
                 });
  }

  TestStore test_store_{GetParam()};
  MapStore& store_ = *test_store_;
};
INSTANTIATE_TEST_SUITE_P(Backends, MapVersionsTest, kAllBackends, BackendName);

TEST_P(MapVersionsTest, EveryVersionStaysReadable) {
  EXPECT_TRUE(store_.ReadMapVersion("m", 1).trees.empty());
  EXPECT_EQ(Ids(store_.ReadMapVersion("m", 2).trees), (std::vector<int64_t>{1, 2, 3}));
  const MapSnapshot v3 = store_.ReadMapVersion("m", 3);
  EXPECT_EQ(Ids(v3.trees), (std::vector<int64_t>{1, 2, 3, 4}));
  EXPECT_EQ(v3.trees[3], Candidate(4, 5, 5, 1));  // state fields round-trip
  EXPECT_EQ(v3.info.tree_count, 4);
  EXPECT_EQ(v3.info.confirmed_count, 3);

  store_.WriteTrees("m", {Tree(9, 1, 1)}, WriteMode::kReplace);  // version 4
  EXPECT_EQ(Ids(store_.ReadMap("m").trees), (std::vector<int64_t>{9}));
  EXPECT_EQ(Ids(store_.ReadMapVersion("m", 0).trees), (std::vector<int64_t>{9}));
  const MapSnapshot old = store_.ReadMapVersion("m", 2);
  EXPECT_EQ(old.info.version, 2);
  EXPECT_EQ(old.info.tree_count, 3);
  ASSERT_TRUE(old.info.extent.has_value());
  EXPECT_EQ(old.info.extent->max_x, 10);
  EXPECT_EQ(old.trees[1], Tree(2, 10, 0));
  // The spatial index answers for the current version only.
  EXPECT_EQ(Ids(store_.TreesInBox("m", Extent{-100, -100, 100, 100})), (std::vector<int64_t>{9}));
  ExpectError([&] { store_.ReadMapVersion("m", 5); }, Code::kNotFound, "has no version 5");
  ExpectError([&] { store_.ReadMapVersion("m", -1); }, Code::kInvalidArgument, "negative");
}

TEST_P(MapVersionsTest, HistoryCountsWhatChanged) {
  const std::vector<VersionRecord> history = store_.ListVersions("m", 0);
  ASSERT_EQ(history.size(), 3u);
  EXPECT_EQ(history[0].kind, VersionKind::kCreate);
  EXPECT_EQ(history[1].kind, VersionKind::kUpload);
  EXPECT_EQ(history[1].trees_added, 3);
  EXPECT_EQ(history[2].kind, VersionKind::kObserve);
  EXPECT_EQ(history[2].source, "drone-a");
  EXPECT_EQ(history[2].tree_count, 4);
  EXPECT_EQ(history[2].confirmed_count, 3);
  EXPECT_EQ(history[2].trees_added, 1);
  EXPECT_EQ(history[2].observations_added, 1);
  const std::vector<VersionRecord> last = store_.ListVersions("m", 1);
  ASSERT_EQ(last.size(), 1u);
  EXPECT_EQ(last[0].version, 3);
}

TEST_P(MapVersionsTest, MergeReadsTheCurrentVersionAndUpdatesInPlaceOfOldRows) {
  const MapInfo info =
      store_.Merge("m", MergeNote{VersionKind::kObserve, "drone-b", 3}, [](MergeReader& reader) {
        EXPECT_EQ(reader.map().version, 3);
        EXPECT_EQ(Ids(reader.TreesInBox(Extent{4, 4, 11, 6})), (std::vector<int64_t>{4}));
        const std::vector<int64_t> ids = {4, 1, 99};
        EXPECT_EQ(Ids(reader.TreesById(ids)), (std::vector<int64_t>{1, 4}));
        const std::vector<ObservationRecord> rows = reader.ObservationsOfSource("drone-a");
        EXPECT_EQ(rows.size(), 1u);
        EXPECT_EQ(rows.at(0).version, 3);
        EXPECT_EQ(rows.at(0).tree_id, 4);
        EXPECT_EQ(reader.ObservationsOfTrees(ids).size(), 1u);
        MapChanges changes;
        TreeRecord confirmed = Candidate(4, 5.5, 5, 2);
        confirmed.status = TreeStatus::kConfirmed;
        changes.put_trees.push_back(confirmed);
        changes.added_observations.push_back(Observation(4, "drone-b", 6, 5));
        changes.removed_trees.push_back(3);
        return changes;
      });
  EXPECT_EQ(info.version, 4);
  EXPECT_EQ(info.tree_count, 3);
  EXPECT_EQ(info.confirmed_count, 3);
  ASSERT_TRUE(info.extent.has_value());
  EXPECT_EQ(info.extent->max_y, 5);  // tree 3 at y = 10 is gone: the extent shrank
  const MapSnapshot now = store_.ReadMap("m");
  EXPECT_EQ(Ids(now.trees), (std::vector<int64_t>{1, 2, 4}));
  EXPECT_EQ(now.trees[2].x, 5.5);
  EXPECT_EQ(store_.ReadMapVersion("m", 3).trees[3].x, 5);  // the old state is still there
  const VersionRecord record = store_.ListVersions("m", 1).at(0);
  EXPECT_EQ(record.trees_updated, 1);
  EXPECT_EQ(record.trees_removed, 1);
  EXPECT_EQ(record.trees_added, 0);
}

TEST_P(MapVersionsTest, StaleOrFailingMergesLeaveThePreviousVersion) {
  const MapSnapshot before = store_.ReadMap("m");
  ExpectError(
      [&] {
        store_.Merge("m", MergeNote{VersionKind::kObserve, "x", 2}, [](MergeReader&) -> MapChanges {
          ADD_FAILURE() << "a stale merge must not run";
          return {};
        });
      },
      Code::kConflict, "not at the base version 2");
  // The merge function throws after reading.
  EXPECT_THROW(store_.Merge("m", MergeNote{},
                            [](MergeReader& reader) -> MapChanges {
                              reader.TreesInBox(Extent{-1, -1, 20, 20});
                              throw std::runtime_error("merge failed");
                            }),
               std::runtime_error);
  // A write fails after thousands of rows went in: everything is undone.
  ExpectError(
      [&] {
        store_.Merge("m", MergeNote{}, [](MergeReader& reader) {
          MapChanges changes;
          int64_t id = reader.NextFreeTreeId();
          for (int i = 0; i < 5000; ++i) {
            changes.put_trees.push_back(Candidate(id, i * 0.1, 1, 1));
            changes.added_observations.push_back(Observation(id++, "drone-c", i * 0.1, 1));
          }
          changes.removed_observations.push_back(123456);  // no such row
          return changes;
        });
      },
      Code::kInvalidArgument, "observation 123456");
  ExpectError(
      [&] {
        store_.Merge("m", MergeNote{}, [](MergeReader&) {
          MapChanges changes;
          changes.removed_trees.push_back(77);
          return changes;
        });
      },
      Code::kInvalidArgument, "tree 77 to remove is not in the map");
  const MapSnapshot after = store_.ReadMap("m");
  EXPECT_EQ(after.info.version, before.info.version);
  EXPECT_EQ(after.trees, before.trees);
  EXPECT_EQ(store_.TreesInBox("m", Extent{-1, -1, 1000, 20}).size(), 4u);
  EXPECT_EQ(store_.ListVersions("m", 0).size(), 3u);
  // Empty changes make no version.
  EXPECT_EQ(store_.Merge("m", MergeNote{}, [](MergeReader&) { return MapChanges{}; }).version, 3);
}

// A merge may name a row to remove once: the second removal of the same tree or observation
// names a row that is no longer current (both backends agree).
TEST_P(MapVersionsTest, RemovingARowTwiceInOneMergeIsRefused) {
  ExpectError(
      [&] {
        store_.Merge("m", MergeNote{}, [](MergeReader&) {
          MapChanges changes;
          changes.removed_trees = {3, 3};
          return changes;
        });
      },
      Code::kInvalidArgument, "tree 3 to remove is not in the map");
  ExpectError(
      [&] {
        store_.Merge("m", MergeNote{}, [](MergeReader& reader) {
          MapChanges changes;
          const int64_t row = reader.ObservationsOfSource("drone-a").at(0).id;
          changes.removed_observations = {row, row};
          return changes;
        });
      },
      Code::kInvalidArgument, "to remove is not current in the map");
  EXPECT_EQ(store_.GetMap("m").version, 3);
  EXPECT_EQ(store_.GetMap("m").tree_count, 4);
}

TEST_P(MapVersionsTest, RestoreBringsBackTreesAndObservations) {
  store_.Merge("m", MergeNote{VersionKind::kRemoveSource, "drone-a", std::nullopt},
               [](MergeReader& reader) {
                 MapChanges changes;
                 for (const ObservationRecord& row : reader.ObservationsOfSource("drone-a")) {
                   changes.removed_observations.push_back(row.id);
                 }
                 changes.removed_trees.push_back(4);
                 return changes;
               });                                                 // version 4
  store_.WriteTrees("m", {Tree(20, 50, 50)}, WriteMode::kAppend);  // version 5
  const MapInfo restored = store_.RestoreVersion("m", 3);
  EXPECT_EQ(restored.version, 6);
  EXPECT_EQ(restored.tree_count, 4);
  EXPECT_EQ(store_.ReadMap("m").trees, store_.ReadMapVersion("m", 3).trees);
  EXPECT_EQ(store_.ReadMap("m").info.extent->max_x, 10);
  EXPECT_EQ(Ids(store_.TreesInBox("m", Extent{-100, -100, 100, 100})),
            (std::vector<int64_t>{1, 2, 3, 4}));
  const VersionRecord record = store_.ListVersions("m", 1).at(0);
  EXPECT_EQ(record.kind, VersionKind::kRestore);
  EXPECT_EQ(record.restored_from, 3);
  EXPECT_EQ(record.trees_added, 1);    // tree 4
  EXPECT_EQ(record.trees_removed, 1);  // tree 20
  // The observation of drone-a is current again, so a later recompute sees it.
  store_.Merge("m", MergeNote{}, [](MergeReader& reader) {
    const std::vector<ObservationRecord> rows = reader.ObservationsOfSource("drone-a");
    EXPECT_EQ(rows.size(), 1u);
    EXPECT_EQ(rows.at(0).tree_id, 4);
    EXPECT_EQ(rows.at(0).x, 5);
    return MapChanges{};
  });
  ExpectError([&] { store_.RestoreVersion("m", 42); }, Code::kNotFound, "has no version 42");
}

}  // namespace
}  // namespace forestmap::storage
