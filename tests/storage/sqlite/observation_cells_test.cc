// SQLite's migration to schema 3, which made the cell index of observation rows: rows of a
// schema-2 database are found by cell afterwards, as a brute-force filter by CellOf finds them.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <set>
#include <string>
#include <vector>

#include "storage/sqlite/database.h"
#include "storage/sqlite/internal.h"
#include "storage/sqlite/store.h"
#include "tests/storage/cell_coordinates.h"
#include "tests/storage/test_directory.h"

namespace forestmap::storage {
namespace {

TEST(ObservationCells, MigrationFromSchemaTwoIndexesExistingRows) {
  const TestDirectory dir;
  const std::string path = dir.File("maps.db");
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
}

}  // namespace
}  // namespace forestmap::storage
