// SqliteMapStore versions (shared maps): every version readable, history, restore, the merge
// transaction (reads and writes in one transaction, all or nothing, stale checks) and the
// migration of a schema-1 database.
#include <gtest/gtest.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "storage/sqlite/database.h"
#include "storage/sqlite/store.h"
#include "tests/storage/store_backends.h"

namespace forestmap::storage {
namespace {

namespace fs = std::filesystem;
using Code = StorageError::Code;

TreeRecord Tree(int64_t id, double x, double y) {
  TreeRecord tree;
  tree.id = id;
  tree.x = x;
  tree.y = y;
  return tree;
}

TreeRecord Candidate(int64_t id, double x, double y, int64_t observations) {
  TreeRecord tree = Tree(id, x, y);
  tree.status = TreeStatus::kCandidate;
  tree.observations = observations;
  tree.position_sigma = 0.05;
  return tree;
}

ObservationRecord Observation(int64_t tree_id, const std::string& source, double x, double y) {
  ObservationRecord o;
  o.tree_id = tree_id;
  o.source = source;
  o.frame_id = 7;
  o.detection_index = 3;
  o.x = x;
  o.y = y;
  o.z = 0.5;
  o.weight_xy = 100;
  o.sensor_x = x - 5;
  o.sensor_y = y;
  return o;
}

std::vector<int64_t> Ids(const std::vector<TreeRecord>& trees) {
  std::vector<int64_t> ids;
  for (const TreeRecord& tree : trees) ids.push_back(*tree.id);
  return ids;
}

template <typename Call>
void ExpectError(Call call, Code code, const std::string& fragment) {
  try {
    call();
    ADD_FAILURE() << "no error; expected one containing '" << fragment << "'";
  } catch (const StorageError& e) {
    EXPECT_EQ(e.code(), code) << e.what();
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
  }
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

// ---- Files: migration and crashes ----

class MapVersionsFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("forestmap_versions_" + std::to_string(getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    path_ = (dir_ / "maps.db").string();
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_;
  std::string path_;
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
