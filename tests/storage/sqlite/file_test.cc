// SqliteMapStore on database files: persistence, schema versions, errors naming the file, and the
// R*Tree blocks a deleted map leaves behind.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "storage/sqlite/database.h"
#include "storage/sqlite/store.h"
#include "tests/storage/store_test_util.h"
#include "tests/storage/test_directory.h"

namespace forestmap::storage {
namespace {

using Code = StorageError::Code;

class SqliteMapStoreFileTest : public ::testing::Test {
 protected:
  // A second, raw connection to look at what the store wrote.
  int64_t Query(const char* sql) {
    sqlite::Database db(path_, SQLITE_OPEN_READONLY, 1000);
    return db.QueryInt64(sql);
  }

  TestDirectory dir_;
  const std::string path_ = dir_.File("maps.db");
};

TEST_F(SqliteMapStoreFileTest, ReopeningKeepsDataAndSchemaVersion) {
  TreeRecord tree = Tree(3, 1.5, -2.25);
  tree.z = 0.125;
  tree.attributes = {{"species", "Pinus sylvestris"}};
  {
    SqliteMapStore store(path_);
    store.CreateMap("plot", "a plot", "EPSG:3067");
    store.WriteTrees("plot", {tree, Tree(4, 0, 0)}, WriteMode::kAppend);
  }
  EXPECT_EQ(Query("PRAGMA user_version"), SqliteMapStore::kSchemaVersion);
  for (int reopen = 0; reopen < 2; ++reopen) {  // migrations must not run again
    SqliteMapStore store(path_);
    const MapSnapshot snapshot = store.ReadMap("plot");
    EXPECT_EQ(snapshot.info.description, "a plot");
    EXPECT_EQ(snapshot.info.crs, "EPSG:3067");
    EXPECT_EQ(snapshot.info.version, 2);
    EXPECT_EQ(snapshot.trees, (std::vector<TreeRecord>{tree, Tree(4, 0, 0)}));
    EXPECT_EQ(store.TreesInBox("plot", Extent{1, -3, 2, -2}), std::vector<TreeRecord>{tree});
  }
  EXPECT_EQ(Query("PRAGMA user_version"), SqliteMapStore::kSchemaVersion);
  sqlite::Database db(path_, SQLITE_OPEN_READONLY, 1000);
  sqlite::Statement mode(db, "PRAGMA journal_mode");
  ASSERT_TRUE(mode.Step());
  EXPECT_EQ(mode.ColumnText(0), "wal");
}

TEST_F(SqliteMapStoreFileTest, RefusesADatabaseFromANewerVersion) {
  const std::string newer = std::to_string(SqliteMapStore::kSchemaVersion + 1);
  {
    sqlite::Database db(path_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, 1000);
    db.Execute(("CREATE TABLE future (x); PRAGMA user_version = " + newer).c_str());
  }
  try {
    SqliteMapStore store(path_);
    ADD_FAILURE() << "a database with schema version " << newer << " was accepted";
  } catch (const StorageError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("schema version " + newer), std::string::npos) << message;
    EXPECT_NE(message.find(path_), std::string::npos) << message;
  }
  EXPECT_EQ(Query("PRAGMA user_version"), SqliteMapStore::kSchemaVersion + 1);  // untouched
}

TEST_F(SqliteMapStoreFileTest, BadFilesGiveErrorsNamingThePath) {
  std::ofstream(path_) << "this is not a database, just some text that is long enough......";
  try {
    SqliteMapStore store(path_);
    ADD_FAILURE() << "a text file was accepted as a database";
  } catch (const StorageError& e) {
    EXPECT_NE(std::string(e.what()).find(path_), std::string::npos) << e.what();
  }
  const std::string missing_dir = (dir_.path() / "no" / "such" / "dir" / "maps.db").string();
  try {
    SqliteMapStore store(missing_dir);
    ADD_FAILURE() << "opened a database in a missing directory";
  } catch (const StorageError& e) {
    EXPECT_NE(std::string(e.what()).find(missing_dir), std::string::npos) << e.what();
  }
  EXPECT_THROW(SqliteMapStore(path_, SqliteMapStoreOptions{.max_readers = 0}), StorageError);
}

TEST_F(SqliteMapStoreFileTest, DeletingAMapRemovesItsTreesAndIndexRows) {
  SqliteMapStore store(path_);
  std::vector<TreeRecord> trees;
  for (int64_t id = 1; id <= 500; ++id) trees.push_back(Tree(id, id * 0.5, -id * 0.25));
  store.CreateMap("gone", "", "");
  store.CreateMap("kept", "", "");
  store.WriteTrees("gone", trees, WriteMode::kAppend);
  store.WriteTrees("kept", {trees.begin(), trees.begin() + 10}, WriteMode::kAppend);
  store.WriteTrees("gone", trees, WriteMode::kReplace);  // the replaced version stays readable
  const int64_t blocks_of_gone =
      (500 + SqliteMapStore::kTreesPerBlock - 1) / SqliteMapStore::kTreesPerBlock;
  EXPECT_EQ(Query("SELECT COUNT(*) FROM tree_blocks"), 2 * blocks_of_gone + 1);
  // Every index row covers trees of its own map.
  const char* kOrphanBlocks =
      "SELECT COUNT(*) FROM tree_blocks AS b WHERE NOT EXISTS (SELECT 1 FROM trees AS t WHERE "
      "t.rowid BETWEEN b.first_rowid AND b.last_rowid AND t.map_id = b.map_id)";
  EXPECT_EQ(Query(kOrphanBlocks), 0);

  store.DeleteMap("gone");
  EXPECT_EQ(Query("SELECT COUNT(*) FROM trees"), 10);
  EXPECT_EQ(Query("SELECT COUNT(*) FROM tree_blocks"), 1);
  EXPECT_EQ(Query("SELECT COUNT(*) FROM map_versions"), 2);  // "kept": created, one upload
  EXPECT_EQ(Query(kOrphanBlocks), 0);
  EXPECT_EQ(store.TreesInBox("kept", Extent{-1e9, -1e9, 1e9, 1e9}).size(), 10u);
  store.CreateMap("gone", "", "");  // a new map of the same name starts empty
  EXPECT_TRUE(store.ReadMap("gone").trees.empty());
  EXPECT_TRUE(store.TreesInBox("gone", Extent{-1e9, -1e9, 1e9, 1e9}).empty());
}

}  // namespace
}  // namespace forestmap::storage
