// SqliteMapStore on database files: persistence, schema versions, index cleanup, concurrency and
// a million-tree map; the concurrency and million-tree tests run on PostgreSQL too.
#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "storage/sqlite/database.h"
#include "storage/sqlite/store.h"
#include "tests/storage/store_backends.h"

namespace forestmap::storage {
namespace {

namespace fs = std::filesystem;
using Code = StorageError::Code;

TreeRecord Tree(std::optional<int64_t> id, double x, double y) {
  TreeRecord tree;
  tree.id = id;
  tree.x = x;
  tree.y = y;
  return tree;
}

// A fresh directory per test, removed afterwards.
class SqliteMapStoreFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("forestmap_storage_" + std::to_string(getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    path_ = (dir_ / "maps.db").string();
  }
  void TearDown() override { fs::remove_all(dir_); }

  // A second, raw connection to look at what the store wrote.
  int64_t Query(const char* sql) {
    sqlite::Database db(path_, SQLITE_OPEN_READONLY, 1000);
    return db.QueryInt64(sql);
  }

  fs::path dir_;
  std::string path_;
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
  const std::string missing_dir = (dir_ / "no" / "such" / "dir" / "maps.db").string();
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

// Readers must always see a committed version whole: count, extent and trees agree, and every
// tree carries the batch marker of that version.
std::string CheckSnapshot(const MapSnapshot& snapshot) {
  const MapInfo& info = snapshot.info;
  if (info.tree_count != static_cast<int64_t>(snapshot.trees.size())) {
    return "tree_count " + std::to_string(info.tree_count) + " but " +
           std::to_string(snapshot.trees.size()) + " trees at version " +
           std::to_string(info.version);
  }
  double max_x = -1e300;
  for (const TreeRecord& tree : snapshot.trees) {
    max_x = std::max(max_x, tree.x);
    if (tree.attributes.at("version") != std::to_string(info.version)) {
      return "tree of version " + tree.attributes.at("version") + " in a snapshot of version " +
             std::to_string(info.version);
    }
  }
  if (!snapshot.trees.empty() && (!info.extent || info.extent->max_x != max_x)) {
    return "extent does not match the trees at version " + std::to_string(info.version);
  }
  return "";
}

// `writes` and `reads` may be one store or two on the same database (two replicas).
void RunConcurrentReadersAndWriter(MapStore& store, MapStore& reader_store) {
  store.CreateMap("busy", "", "");
  constexpr int kWrites = 100;
  constexpr int kReaders = 3;
  std::atomic<bool> done{false};
  std::mutex failures_mutex;
  std::vector<std::string> failures;
  std::atomic<int64_t> reads{0};
  const auto fail = [&](const std::string& what) {
    std::lock_guard<std::mutex> lock(failures_mutex);
    failures.push_back(what);
  };
  const auto failures_count = [&] {
    std::lock_guard<std::mutex> lock(failures_mutex);
    return failures.size();
  };

  std::thread writer([&] {
    try {
      while (reads < kReaders && failures_count() == 0) std::this_thread::yield();  // overlap
      for (int i = 0; i < kWrites; ++i) {
        // Version i + 2 replaces all trees with a batch whose size changes every time.
        const std::string version = std::to_string(i + 2);
        std::vector<TreeRecord> trees;
        for (int k = 0; k < 1 + (i * 37) % 700; ++k) {
          TreeRecord tree = Tree(std::nullopt, k, i);
          tree.attributes["version"] = version;
          trees.push_back(tree);
        }
        store.WriteTrees("busy", trees, WriteMode::kReplace);
        store.CreateMap("tmp" + std::to_string(i), "", "");  // other writes in between
        if (i % 2 == 1) store.DeleteMap("tmp" + std::to_string(i - 1));
      }
    } catch (const std::exception& e) {
      fail(std::string("writer: ") + e.what());
    }
    done = true;
  });
  std::vector<std::thread> readers;
  for (int r = 0; r < kReaders; ++r) {
    readers.emplace_back([&] {
      try {
        while (!done) {
          const std::string problem = CheckSnapshot(reader_store.ReadMap("busy"));
          if (!problem.empty()) fail(problem);
          const MapInfo info = reader_store.GetMap("busy");
          if (info.version < 1) fail("bad version");
          reader_store.TreesInBox("busy", Extent{0, 0, 100, 100});
          reader_store.ListMaps();
          ++reads;
        }
      } catch (const std::exception& e) {
        fail(std::string("reader: ") + e.what());
      }
    });
  }
  writer.join();
  for (std::thread& reader : readers) reader.join();
  EXPECT_TRUE(failures.empty()) << failures.size() << " failures, first: " << failures.front();
  EXPECT_GT(reads.load(), 0);
  EXPECT_EQ(store.GetMap("busy").version, kWrites + 1);
  EXPECT_EQ(CheckSnapshot(store.ReadMap("busy")), "");
}

TEST_F(SqliteMapStoreFileTest, ConcurrentReadersSeeConsistentSnapshots) {
  SqliteMapStore store(path_, SqliteMapStoreOptions{.max_readers = 2});
  RunConcurrentReadersAndWriter(store, store);
}

TEST(SqliteMapStoreMemoryTest, ConcurrentReadersSeeConsistentSnapshots) {
  SqliteMapStore store(":memory:");
  RunConcurrentReadersAndWriter(store, store);
}

TEST(PostgresMapStoreTest, ConcurrentReadersSeeConsistentSnapshots) {
  TestStore store(Backend::kPostgres);
  RunConcurrentReadersAndWriter(*store, *store);
}

// Two stores on one database, as two forestmapd replicas: readers of one see whole versions
// that the other writes.
TEST(PostgresMapStoreTest, AnotherReplicaSeesConsistentSnapshots) {
  TestStore store(Backend::kPostgres);
  const std::unique_ptr<MapStore> replica = store.Another();
  RunConcurrentReadersAndWriter(*store, *replica);
}

// A survey-sized map goes through one write and one read whole, and the spatial index answers
// small boxes exactly (a query plan that scanned the map per block would make this crawl).
void MillionTreeMapWritesAndReadsBack(MapStore& store) {
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

TEST_F(SqliteMapStoreFileTest, MillionTreeMapWritesAndReadsBack) {
  SqliteMapStore store(path_);
  MillionTreeMapWritesAndReadsBack(store);
}

TEST(PostgresMapStoreTest, MillionTreeMapWritesAndReadsBack) {
  TestStore store(Backend::kPostgres);
  MillionTreeMapWritesAndReadsBack(*store);
}

}  // namespace
}  // namespace forestmap::storage
