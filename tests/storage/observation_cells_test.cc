// The cell index of current observation rows (MergeReader::ObservationsInCells): the rows it
// returns against a brute-force filter by CellOf, across negative coordinates and cell edges,
// after rows are closed, and after a schema-2 database with rows is migrated.
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "storage/sqlite/database.h"
#include "storage/sqlite/store.h"
#include "storage/sqlite/internal.h"
#include "tests/storage/store_backends.h"

namespace forestmap::storage {
namespace {

namespace fs = std::filesystem;

// Coordinates on both sides of cell edges (multiples of kObservationCellSize), around 0 and
// far out, in both signs.
std::vector<double> Coordinates() {
  const double s = kObservationCellSize;
  return {-2 * s - 1e-9, -2 * s,   -s, -s + 1e-12,   -1e-300,   0.0,       1e-12,
          0.5 * s,       s - 1e-9, s,  3 * s + 0.25, 1e6 + 0.1, -1e6 - 0.1};
}

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

// The cells of the first column of rows and of both diagonals, and two around the origin.
std::vector<ObservationCell> SomeCells() {
  std::vector<ObservationCell> cells;
  for (const double x : Coordinates()) {
    cells.push_back(CellOf(Coordinates().front(), x));
    cells.push_back(CellOf(x, x));
    cells.push_back(CellOf(x, -x));
  }
  cells.push_back({-1, 0});
  cells.push_back({0, -1});
  return cells;
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

TEST(ObservationCells, MigrationFromSchemaTwoIndexesExistingRows) {
  const fs::path dir = fs::temp_directory_path() / ("forestmap_cells_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string path = (dir / "maps.db").string();
  {
    sqlite::Database db(path, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, 1000);
    db.Execute(sqlite::SchemaSteps().at(0));
    db.Execute(sqlite::SchemaSteps().at(1));
    ASSERT_EQ(db.QueryInt64("PRAGMA user_version"), 2);
    db.Execute(
        "INSERT INTO maps (id, name, description, crs, version, tree_count, created_unix_ms, "
        "updated_unix_ms, confirmed_count) VALUES (1, 'm', '', '', 1, 0, 0, 0, 0)");
    sqlite::Statement insert(
        db,
        "INSERT INTO observations (map_id, tree_id, valid_from, valid_to, source, frame_id, "
        "detection_index, x, y, weight_xy, weight_dbh, sensor_x, sensor_y, sensor_z, prior) "
        "VALUES (1, 1, 1, 9223372036854775807, 'drone', 1, ?1, ?2, ?3, 1, 0, 0, 0, 0, 0)");
    int detection = 0;
    for (const double x : Coordinates()) {
      for (const double y : Coordinates()) {
        insert.BindInt64(1, detection++);
        insert.BindDouble(2, x);
        insert.BindDouble(3, y);
        insert.Run();
      }
    }
  }
  {
    SqliteMapStore store(path);  // migrates to the current schema
    store.Merge("m", MergeNote{}, [](MergeReader& reader) {
      std::vector<ObservationRecord> all = reader.ObservationsOfTrees(std::vector<int64_t>{1});
      EXPECT_EQ(all.size(), Coordinates().size() * Coordinates().size());
      std::set<int64_t> expected, found;
      const std::vector<ObservationCell> cells = SomeCells();
      const std::set<ObservationCell> wanted(cells.begin(), cells.end());
      for (const ObservationRecord& row : all) {
        if (wanted.count(CellOf(row.x, row.y)) != 0) expected.insert(row.id);
      }
      for (const ObservationRecord& row : reader.ObservationsInCells(cells)) found.insert(row.id);
      EXPECT_EQ(found, expected);
      EXPECT_FALSE(found.empty());
      return MapChanges{};
    });
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace forestmap::storage
