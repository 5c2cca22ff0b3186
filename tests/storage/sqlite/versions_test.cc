// SqliteMapStore versions on files: the migration of a schema-1 database, and a process killed in
// the middle of a merge.
#include <gtest/gtest.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <vector>

#include "storage/sqlite/database.h"
#include "storage/sqlite/store.h"
#include "tests/storage/store_test_util.h"
#include "tests/storage/test_directory.h"

namespace forestmap::storage {
namespace {

namespace fs = std::filesystem;
using Code = StorageError::Code;

class MapVersionsFileTest : public ::testing::Test {
 protected:
  TestDirectory dir_;
  const std::string path_ = dir_.File("maps.db");
};

// The schema of version 1 as shipped, with a map at version 3 holding two trees and an index
// block, as the previous release wrote it.
constexpr const char* kSchema1Database = R"sql(
CREATE TABLE maps (id INTEGER PRIMARY KEY, name TEXT NOT NULL UNIQUE, description TEXT NOT NULL,
  crs TEXT NOT NULL, version INTEGER NOT NULL, tree_count INTEGER NOT NULL, min_x REAL, min_y REAL,
  max_x REAL, max_y REAL, created_unix_ms INTEGER NOT NULL, updated_unix_ms INTEGER NOT NULL);
CREATE TABLE trees (rowid INTEGER PRIMARY KEY,
  map_id INTEGER NOT NULL REFERENCES maps(id) ON DELETE CASCADE, tree_id INTEGER NOT NULL,
  x REAL NOT NULL, y REAL NOT NULL, z REAL, dbh REAL, attributes TEXT, UNIQUE (map_id, tree_id));
CREATE VIRTUAL TABLE tree_blocks USING rtree(
  id, min_map, max_map, min_x, max_x, min_y, max_y, +map_id, +first_rowid, +last_rowid);
INSERT INTO maps VALUES (1, 'old', 'from v1', 'EPSG:3067', 3, 2, 1, 2, 3, 4, 1000, 2000);
INSERT INTO trees VALUES (1, 1, 7, 1, 2, 0.5, 0.3, '{"species":"Pinus"}');
INSERT INTO trees VALUES (2, 1, 8, 3, 4, NULL, NULL, NULL);
INSERT INTO tree_blocks VALUES (1, 1, 1, 1, 3, 2, 4, 1, 1, 2);
PRAGMA user_version = 1;
)sql";

TEST_F(MapVersionsFileTest, MigratesASchemaOneDatabase) {
  {
    sqlite::Database db(path_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, 1000);
    db.Execute(kSchema1Database);
  }
  TreeRecord first = Tree(7, 1, 2);
  first.z = 0.5;
  first.dbh = 0.3;
  first.attributes = {{"species", "Pinus"}};
  {
    SqliteMapStore store(path_);
    const MapSnapshot snapshot = store.ReadMap("old");
    EXPECT_EQ(snapshot.info.version, 3);
    EXPECT_EQ(snapshot.info.tree_count, 2);
    EXPECT_EQ(snapshot.info.confirmed_count, 2);
    EXPECT_EQ(snapshot.info.updated_unix_ms, 2000);
    EXPECT_EQ(snapshot.trees, (std::vector<TreeRecord>{first, Tree(8, 3, 4)}));
    EXPECT_EQ(store.TreesInBox("old", Extent{0, 0, 2, 3}), std::vector<TreeRecord>{first});
    const std::vector<VersionRecord> history = store.ListVersions("old", 0);
    ASSERT_EQ(history.size(), 1u);
    EXPECT_EQ(history[0].kind, VersionKind::kMigrated);
    EXPECT_EQ(history[0].version, 3);
    ExpectError([&] { store.ReadMapVersion("old", 2); }, Code::kNotFound,
                "versions 3 to 3 can be read");
    // The migrated map takes writes, and its migrated version stays readable.
    store.WriteTrees("old", {Tree(9, 5, 5)}, WriteMode::kAppend);
    EXPECT_EQ(store.ReadMapVersion("old", 3).trees.size(), 2u);
  }
  sqlite::Database db(path_, SQLITE_OPEN_READONLY, 1000);
  EXPECT_EQ(db.QueryInt64("PRAGMA user_version"), SqliteMapStore::kSchemaVersion);
  sqlite::Statement check(db, "PRAGMA integrity_check");
  ASSERT_TRUE(check.Step());
  EXPECT_EQ(check.ColumnText(0), "ok");
}

// A process killed (SIGKILL) in the middle of a large merge: the file keeps the previous
// version whole and passes SQLite's integrity check.
TEST_F(MapVersionsFileTest, KilledInTheMiddleOfAMergeKeepsThePreviousVersion) {
  constexpr int kTrees = 20'000;
  {
    SqliteMapStore store(path_);
    store.CreateMap("m", "", "");
    std::vector<TreeRecord> trees;
    for (int i = 0; i < kTrees; ++i) trees.push_back(Tree(i + 1, i % 200, i / 200));
    store.WriteTrees("m", trees, WriteMode::kAppend);  // version 2
  }
  int ready[2];
  ASSERT_EQ(pipe(ready), 0);
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    // Child: a merge that rewrites every tree and adds 10 observations each, with a tiny page
    // cache so that pages spill to the WAL file while the transaction is open.
    close(ready[0]);
    try {
      SqliteMapStore store(path_, SqliteMapStoreOptions{.cache_mib = 1});
      store.Merge("m", MergeNote{}, [&](MergeReader& reader) {
        MapChanges changes;
        for (TreeRecord& tree : reader.TreesInBox(Extent{-1, -1, 1000, 1000})) {
          for (int k = 0; k < 10; ++k) {
            changes.added_observations.push_back(Observation(*tree.id, "crash", tree.x, tree.y));
          }
          tree.x += 0.5;
          tree.observations = 10;
          changes.put_trees.push_back(tree);
        }
        for (int round = 0; round < 10; ++round) {  // make the write long
          const auto more = changes.added_observations;
          changes.added_observations.insert(changes.added_observations.end(), more.begin(),
                                            more.begin() + kTrees);
        }
        const char go = 'g';
        if (write(ready[1], &go, 1) != 1) _exit(3);
        return changes;
      });
    } catch (...) {
      _exit(2);
    }
    _exit(0);  // finished before being killed: the parent reports it
  }
  close(ready[1]);
  char go = 0;
  ASSERT_EQ(read(ready[0], &go, 1), 1);  // the child is about to write
  close(ready[0]);
  const std::string wal = path_ + "-wal";
  // Kill once the transaction has spilled a few MB into the WAL (or after ~10 s at most).
  for (int i = 0; i < 10'000; ++i) {
    std::error_code error;
    if (fs::file_size(wal, error) > (4u << 20)) break;
    usleep(1000);
  }
  kill(child, SIGKILL);
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFSIGNALED(status))
      << "the merge finished before it could be killed (status " << status << "); make it larger";

  SqliteMapStore store(path_);
  const MapSnapshot snapshot = store.ReadMap("m");
  EXPECT_EQ(snapshot.info.version, 2);
  ASSERT_EQ(snapshot.trees.size(), static_cast<size_t>(kTrees));
  EXPECT_EQ(snapshot.trees[201].x, 1);  // not moved by the killed merge
  EXPECT_EQ(store.ListVersions("m", 0).size(), 2u);
  EXPECT_EQ(store.TreesInBox("m", Extent{-1, -1, 1000, 1000}).size(), static_cast<size_t>(kTrees));
  sqlite::Database db(path_, SQLITE_OPEN_READONLY, 1000);
  EXPECT_EQ(db.QueryInt64("SELECT COUNT(*) FROM observations"), 0);
  sqlite::Statement check(db, "PRAGMA integrity_check");
  ASSERT_TRUE(check.Step());
  EXPECT_EQ(check.ColumnText(0), "ok");
}

}  // namespace
}  // namespace forestmap::storage
