// The cell index of current observation rows (MergeReader::ObservationsInCells) on every
// backend: the rows it returns against a brute-force filter by CellOf, across negative
// coordinates and cell edges, and after rows are closed. Folded rows: a merge reads the summary
// row in their place, by cell and by tree; they stay the source's, and every version keeps them.
#include <gtest/gtest.h>

#include <algorithm>
#include <set>
#include <string>
#include <vector>

#include "tests/storage/cell_coordinates.h"
#include "tests/storage/store_backends.h"

namespace forestmap::storage {
namespace {

ObservationRecord Row(int64_t tree_id, double x, double y) {
  ObservationRecord o;
  o.tree_id = tree_id;
  o.source = "drone";
  o.frame_id = tree_id;
  o.x = x;
  o.y = y;
  o.weight_xy = 100;
  return o;
}

// Ids of the current rows in `cells`, by the index and by a brute-force filter.
void ExpectCellsAgree(MergeReader& reader, const std::vector<ObservationCell>& cells) {
  const std::set<ObservationCell> wanted(cells.begin(), cells.end());
  std::vector<int64_t> brute, indexed;
  const std::vector<int64_t> all_trees = [&] {
    std::vector<int64_t> ids;
    for (const TreeRecord& tree : reader.TreesInBox(Extent{-1e7, -1e7, 1e7, 1e7})) {
      ids.push_back(*tree.id);
    }
    return ids;
  }();
  for (const ObservationRecord& row : reader.ObservationsOfTrees(all_trees)) {
    if (wanted.count(CellOf(row.x, row.y)) != 0) brute.push_back(row.id);
  }
  for (const ObservationRecord& row : reader.ObservationsInCells(cells)) {
    EXPECT_EQ(wanted.count(CellOf(row.x, row.y)), 1u) << row.x << ", " << row.y;
    indexed.push_back(row.id);
  }
  EXPECT_TRUE(std::is_sorted(indexed.begin(), indexed.end()));
  EXPECT_EQ(indexed, brute);
  EXPECT_FALSE(indexed.empty());
}

// One tree (at the row) per coordinate pair; the rows of the first column are closed later.
void WriteRows(MapStore& store) {
  store.Merge("m", MergeNote{}, [](MergeReader& reader) {
    MapChanges changes;
    int64_t id = reader.NextFreeTreeId();
    for (const double x : Coordinates()) {
      for (const double y : Coordinates()) {
        TreeRecord tree;
        tree.id = id;
        tree.x = x, tree.y = y;
        tree.observations = 1;
        changes.put_trees.push_back(tree);
        changes.added_observations.push_back(Row(id++, x, y));
      }
    }
    return changes;
  });
}

TEST(ObservationCells, CellOfIsTheFloorOfCoordinateOverCellSize) {
  const double s = kObservationCellSize;
  EXPECT_EQ(CellOf(0, 0), (ObservationCell{0, 0}));
  EXPECT_EQ(CellOf(-1e-300, s), (ObservationCell{-1, 1}));
  EXPECT_EQ(CellOf(-s, s - 1e-9), (ObservationCell{-1, 0}));
  EXPECT_EQ(CellOf(-s - 1e-9, 2.5 * s), (ObservationCell{-2, 2}));
}

class ObservationCellsIndex : public ::testing::TestWithParam<Backend> {};
INSTANTIATE_TEST_SUITE_P(Backends, ObservationCellsIndex, kAllBackends, BackendName);

TEST_P(ObservationCellsIndex, FindsExactlyTheCurrentRowsOfTheCells) {
  TestStore test_store(GetParam());
  MapStore& store = *test_store;
  store.CreateMap("m", "", "");
  WriteRows(store);
  // Close the rows of the first x column (moved to another tree, as a rebuild does).
  store.Merge("m", MergeNote{}, [](MergeReader& reader) {
    MapChanges changes;
    const double x = Coordinates().front();
    for (const ObservationRecord& row : reader.ObservationsInCells(SomeCells())) {
      if (row.x != x) continue;
      changes.removed_observations.push_back(row.id);
    }
    EXPECT_FALSE(changes.removed_observations.empty());
    return changes;
  });
  store.Merge("m", MergeNote{}, [](MergeReader& reader) {
    ExpectCellsAgree(reader, SomeCells());
    for (const ObservationRecord& row : reader.ObservationsInCells(SomeCells())) {
      EXPECT_NE(row.x, Coordinates().front());  // closed rows are not current
    }
    EXPECT_TRUE(reader.ObservationsInCells(std::vector<ObservationCell>{{99, 99}}).empty());
    return MapChanges{};
  });
}

// Ids of rows.
std::vector<int64_t> Ids(const std::vector<ObservationRecord>& rows) {
  std::vector<int64_t> ids;
  for (const ObservationRecord& row : rows) ids.push_back(row.id);
  return ids;
}

TEST_P(ObservationCellsIndex, FoldedRowsLeaveWhatAMergeReadsAndStayInTheVersions) {
  TestStore test_store(GetParam());
  MapStore& store = *test_store;
  store.CreateMap("m", "", "");
  const std::vector<int64_t> tree{1};
  const std::vector<ObservationCell> cell{CellOf(1, 1)};
  store.Merge("m", MergeNote{}, [](MergeReader&) {  // version 2: tree 1 with 5 rows
    MapChanges changes;
    TreeRecord one;
    one.id = 1, one.x = 1, one.y = 1, one.observations = 5;
    changes.put_trees.push_back(one);
    for (int k = 0; k < 5; ++k) changes.added_observations.push_back(Row(1, 1 + 0.01 * k, 1));
    return changes;
  });
  std::vector<ObservationRecord> raw;
  store.Merge("m", MergeNote{}, [&](MergeReader& reader) {  // version 3: folded
    raw = reader.ObservationsOfTrees(tree);
    EXPECT_EQ(Ids(reader.ObservationsInCells(cell)), Ids(raw));
    MapChanges changes;
    changes.folded_observations = raw;
    ObservationRecord summary = Row(1, 1.02, 1);
    summary.source = "";
    summary.summary = "1 5";
    changes.added_observations.push_back(summary);
    return changes;
  });
  ASSERT_EQ(raw.size(), 5u);
  const VersionRecord fold = store.ListVersions("m", 1).front();
  EXPECT_EQ(fold.version, 3);
  EXPECT_EQ(fold.observations_added, 0);  // neither the summary nor the copies count
  EXPECT_EQ(fold.observations_removed, 0);
  int64_t summary_id = 0;
  store.Merge("m", MergeNote{}, [&](MergeReader& reader) {
    const std::vector<ObservationRecord> read = reader.ObservationsOfTrees(tree);
    EXPECT_EQ(Ids(reader.ObservationsInCells(cell)), Ids(read));
    EXPECT_EQ(read.size(), 1u);
    if (read.size() == 1) {
      EXPECT_EQ(read[0].summary, std::optional<std::string>("1 5"));
      EXPECT_FALSE(read[0].folded);
      summary_id = read[0].id;
    }
    const std::vector<ObservationRecord> folded = reader.FoldedObservationsOfTrees(tree);
    EXPECT_EQ(Ids(reader.ObservationsOfSource("drone")), Ids(folded));
    EXPECT_EQ(folded.size(), raw.size());
    for (size_t k = 0; k < std::min(folded.size(), raw.size()); ++k) {
      EXPECT_TRUE(folded[k].folded);
      EXPECT_FALSE(folded[k].summary);
      EXPECT_EQ(folded[k].x, raw[k].x);
      EXPECT_EQ(folded[k].version, 3);
    }
    return MapChanges{};
  });
  // A summary that is not current cannot be removed.
  EXPECT_THROW(store.Merge("m", MergeNote{},
                           [&](MergeReader&) {
                             MapChanges changes;
                             changes.removed_summaries.push_back(summary_id + 1000);
                             return changes;
                           }),
               StorageError);
  // Restoring the version before the fold gives the rows back unfolded, without the summary.
  store.RestoreVersion("m", 2);
  store.Merge("m", MergeNote{}, [&](MergeReader& reader) {
    const std::vector<ObservationRecord> read = reader.ObservationsOfTrees(tree);
    EXPECT_EQ(read.size(), 5u);
    for (const ObservationRecord& row : read) EXPECT_FALSE(row.folded || row.summary);
    EXPECT_TRUE(reader.FoldedObservationsOfTrees(tree).empty());
    return MapChanges{};
  });
}

}  // namespace
}  // namespace forestmap::storage
