// Uploads staged in a SQLite file (bounded memory; storage/sqlite/upload.cc): rows are
// in the database before the upload commits, other writers go on between its chunks, a create
// with trees is atomic, an abandoned upload (or one a killed server left) leaves nothing.

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <future>
#include <string>
#include <vector>

#include "storage/backup.h"
#include "storage/sqlite/database.h"
#include "storage/sqlite/store.h"
#include "storage/staged_writes.h"
#include "tests/storage/store_test_util.h"
#include "tests/storage/test_directory.h"

namespace forestmap::storage {
namespace {

using Code = StorageError::Code;

class StagedUploadTest : public ::testing::Test {
 protected:
  // Staged, not committed tree rows (pending ones, and the rows of maps being created) and
  // uploads in the file, read by another connection.
  int64_t Pending(const std::string& path) {
    sqlite::Database db(path, SQLITE_OPEN_READONLY, 1000);
    return db.QueryInt64(
               "SELECT COUNT(*) FROM trees WHERE valid_to < 0 OR map_id IN (SELECT id "
               "FROM maps WHERE creating_upload IS NOT NULL)") +
           db.QueryInt64("SELECT COUNT(*) FROM uploads");
  }

  TestDirectory dir_;
  const std::string path_ = dir_.File("maps.db");
};

TEST_F(StagedUploadTest, RowsAreInTheDatabaseBeforeTheCommitAndVisibleOnlyAfter) {
  SqliteMapStore store(path_);
  store.CreateMap("a", "", "");
  auto upload = store.BeginUpload("a", UploadPlan{});
  upload->Append(Grid(3000));
  upload->Append(Grid(2000));
  EXPECT_EQ(upload->staged(), 5000);
  EXPECT_EQ(Pending(path_), 5000 + 1);  // the rows and the upload's own row
  EXPECT_EQ(store.GetMap("a").tree_count, 0);
  EXPECT_TRUE(store.ReadMap("a").trees.empty());
  EXPECT_TRUE(store.TreesInBox("a", Extent{-1, -1, 1000, 1000}).empty());
  const MapInfo info = upload->Commit();
  EXPECT_EQ(info.tree_count, 5000);
  EXPECT_EQ(info.version, 2);
  const MapSnapshot snapshot = store.ReadMap("a");
  ASSERT_EQ(snapshot.trees.size(), 5000u);
  EXPECT_EQ(*snapshot.trees.front().id, 1);  // ids in upload order, from 1
  EXPECT_EQ(*snapshot.trees.back().id, 5000);
  EXPECT_EQ(store.TreesInBox("a", Extent{0, 0, 1, 1}).size(), 8u);  // 4 places, in both chunks
  EXPECT_EQ(Pending(path_), 0);
}

TEST_F(StagedUploadTest, OtherMapsAreWrittenWhileAnUploadStreams) {
  SqliteMapStore store(path_);
  store.CreateMap("a", "", "");
  auto upload = store.BeginUpload("a", UploadPlan{});
  upload->Append(Grid(5000));
  // Another thread writes map B while A's upload is half-way: it completes before A commits.
  auto other = std::async(std::launch::async, [&] {
    store.CreateMap("b", "", "");
    store.WriteTrees("b", Grid(10), WriteMode::kAppend);
    return store.GetMap("b");
  });
  ASSERT_EQ(other.wait_for(std::chrono::seconds(20)), std::future_status::ready);
  EXPECT_EQ(other.get().tree_count, 10);
  EXPECT_EQ(store.GetMap("a").tree_count, 0);  // A has not committed yet
  upload->Append(Grid(5000, 100000));
  EXPECT_EQ(upload->Commit().tree_count, 10000);
  EXPECT_EQ(store.GetMap("b").tree_count, 10);
}

TEST_F(StagedUploadTest, CreateWithTreesIsAtomic) {
  SqliteMapStore store(path_);
  UploadPlan plan;
  plan.create_map = true;
  plan.description = "plot";
  {
    auto upload = store.BeginUpload("new", plan);
    upload->Append(Grid(100));
    EXPECT_EQ(CodeOf([&] { store.GetMap("new"); }), Code::kNotFound);  // not there yet
    EXPECT_TRUE(store.ListMaps().empty());
    EXPECT_EQ(CodeOf([&] { store.CreateMap("new", "", ""); }), Code::kAlreadyExists);
    EXPECT_EQ(CodeOf([&] { store.BeginUpload("new", plan); }), Code::kAlreadyExists);
  }  // dropped without a commit: nothing is left
  EXPECT_EQ(Pending(path_), 0);
  EXPECT_EQ(CodeOf([&] { store.GetMap("new"); }), Code::kNotFound);

  auto upload = store.BeginUpload("new", plan);
  upload->Append(Grid(100));
  const MapInfo info = upload->Commit();
  EXPECT_EQ(info.tree_count, 100);
  EXPECT_EQ(store.GetMap("new").description, "plot");
  EXPECT_EQ(store.ListVersions("new", 0).size(), 2u);  // created, then its trees
  EXPECT_EQ(CodeOf([&] { store.BeginUpload("new", plan); }), Code::kAlreadyExists);
}

TEST_F(StagedUploadTest, AnUploadLeftByAKilledServerIsRemovedWhenTheDatabaseOpens) {
  const std::string copy = dir_.File("copy.db");
  {
    SqliteMapStore store(path_);
    store.CreateMap("kept", "", "");
    store.WriteTrees("kept", Grid(10), WriteMode::kAppend);
    UploadPlan plan;
    plan.create_map = true;
    auto creating = store.BeginUpload("half", plan);
    creating->Append(Grid(500));
    auto appending = store.BeginUpload("kept", UploadPlan{});
    appending->Append(Grid(300));
    // The state a kill -9 leaves: the staged rows committed, the uploads never finished.
    BackupDatabase(path_, copy);
  }
  EXPECT_EQ(Pending(copy), 800 + 2);
  SqliteMapStore reopened(copy);
  EXPECT_EQ(Pending(copy), 0);
  EXPECT_EQ(CodeOf([&] { reopened.GetMap("half"); }), Code::kNotFound);
  EXPECT_EQ(reopened.GetMap("kept").tree_count, 10);
  EXPECT_EQ(reopened.ReadMap("kept").trees.size(), 10u);
  EXPECT_EQ(reopened.CreateMap("half", "", "").version, 1);  // the same command now works
}

TEST_F(StagedUploadTest, DuplicateIdsAreNamedByTheirIndexInTheUpload) {
  SqliteMapStore store(path_);
  store.CreateMap("a", "", "");
  store.WriteTrees("a", Grid(5, 1), WriteMode::kAppend);  // ids 1..5
  {
    auto upload = store.BeginUpload("a", UploadPlan{});
    upload->Append(Grid(10, 100));  // ids 100..109: trees[0..9]
    try {
      upload->Append(Grid(10, 105));  // trees[10] has id 105, as trees[5]
      FAIL() << "no error";
    } catch (const StorageError& e) {
      EXPECT_EQ(e.code(), Code::kInvalidArgument);
      EXPECT_NE(std::string(e.what()).find("trees[10].id 105 duplicates trees[5].id"),
                std::string::npos)
          << e.what();
    }
  }
  auto clash = store.BeginUpload("a", UploadPlan{});
  clash->Append(Grid(3, 4));  // ids 4, 5 are in the map
  try {
    clash->Commit();
    FAIL() << "no error";
  } catch (const StorageError& e) {
    EXPECT_EQ(e.code(), Code::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("already exists in the map"), std::string::npos);
  }
  EXPECT_EQ(store.GetMap("a").tree_count, 5);
  EXPECT_EQ(store.GetMap("a").version, 2);
  EXPECT_EQ(Pending(path_), 0);
}

TEST_F(StagedUploadTest, ReplaceDeleteAndPruneDuringAnUpload) {
  SqliteMapStore store(path_);
  store.CreateMap("a", "", "");
  store.WriteTrees("a", Grid(20, 1), WriteMode::kAppend);
  UploadPlan replace;
  replace.mode = WriteMode::kReplace;
  auto upload = store.BeginUpload("a", replace);
  upload->Append(Grid(7, 1));
  store.WriteTrees("a", Grid(1, 50), WriteMode::kAppend);  // version 3
  store.PruneVersions("a", 1);                             // must keep the staged rows
  upload->Append(Grid(3));                                 // auto ids above 7
  const MapInfo info = upload->Commit();
  EXPECT_EQ(info.tree_count, 10);
  const MapSnapshot snapshot = store.ReadMap("a");
  ASSERT_EQ(snapshot.trees.size(), 10u);
  EXPECT_EQ(*snapshot.trees.back().id, 10);

  auto orphan = store.BeginUpload("a", UploadPlan{});
  orphan->Append(Grid(4));
  store.DeleteMap("a");
  EXPECT_EQ(CodeOf([&] { orphan->Append(Grid(4)); }), Code::kNotFound);
  orphan.reset();
  EXPECT_EQ(Pending(path_), 0);
}

}  // namespace
}  // namespace forestmap::storage
