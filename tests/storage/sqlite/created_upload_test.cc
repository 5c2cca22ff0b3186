// Issue 15, writers per map on SQLite (schema step 7): an upload that creates its map writes its
// trees as the final rows of the hidden map, so its commit changes a few rows whatever its size
// and holds SQLite's single writer for a moment, not seconds per million trees; a write to
// another map does not wait behind it. Also the migration of a step-6 database (with an upload
// a killed server left) to step 7.

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <future>
#include <string>
#include <vector>

#include "storage/sqlite/database.h"
#include "storage/sqlite/internal.h"
#include "storage/sqlite/store.h"
#include "storage/staged_writes.h"
#include "tests/storage/test_directory.h"

namespace forestmap::storage {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr int kChunk = 10'000;  // trees per Append, as the server stages them

std::vector<TreeRecord> Chunk(int64_t first, int count) {
  std::vector<TreeRecord> trees(static_cast<size_t>(count));
  for (int i = 0; i < count; ++i) {
    trees[static_cast<size_t>(i)].x = static_cast<double>((first + i) % 500) * 2.0;
    trees[static_cast<size_t>(i)].y = static_cast<double>((first + i) / 500) * 2.0;
    trees[static_cast<size_t>(i)].dbh = 0.2;
  }
  return trees;
}

std::unique_ptr<TreeUpload> StagedCreate(SqliteMapStore& store, const std::string& name,
                                         int64_t trees) {
  UploadPlan plan;
  plan.create_map = true;
  auto upload = store.BeginUpload(name, plan);
  for (int64_t first = 0; first < trees; first += kChunk) upload->Append(Chunk(first, kChunk));
  return upload;
}

class CreatedUploadTest : public ::testing::Test {
 protected:
  TestDirectory dir_;
  const std::string path_ = dir_.File("maps.db");
};

// The commit's pages in the write-ahead log: the WAL is emptied (TRUNCATE checkpoint) just
// before it, so its size afterwards is what the commit wrote. Turning 100,000 staged rows
// current one by one (schema step 6) wrote thousands of pages (every row and two index entries).
TEST_F(CreatedUploadTest, TheCommitWritesAFewPagesWhateverTheUploadsSize) {
  SqliteMapStore store(path_);
  for (const int64_t trees : {20'000, 100'000}) {
    const std::string name = "map" + std::to_string(trees);
    auto upload = StagedCreate(store, name, trees);
    {
      sqlite::Database other(path_, SQLITE_OPEN_READWRITE, 5000);
      other.Execute("PRAGMA wal_checkpoint(TRUNCATE)");
    }
    ASSERT_EQ(fs::file_size(path_ + "-wal"), 0u) << "the checkpoint did not empty the WAL";
    EXPECT_EQ(upload->Commit().tree_count, trees);
    constexpr uint64_t kWalHeader = 32, kFrameHeader = 24, kPage = 4096;
    const uint64_t frames = (fs::file_size(path_ + "-wal") - kWalHeader) / (kFrameHeader + kPage);
    EXPECT_LT(frames, 64u) << trees << " trees";
    std::printf("commit of %lld staged trees: %llu WAL frames\n", static_cast<long long>(trees),
                static_cast<unsigned long long>(frames));
    EXPECT_EQ(store.ReadMap(name).trees.size(), static_cast<size_t>(trees));
    EXPECT_EQ(store.TreesInBox(name, Extent{0, 0, 3, 3}).size(), 4u);
  }
}

// A long upload creating map A, committed on another thread while this one writes map B again
// and again: B is written all along A's upload (A's writer transactions are a chunk or the
// commit, never the whole upload). How long the slowest write of B waits is printed, not
// asserted: a figure of time belongs to the benchmarks (tests/bench/upload_commit_bench).
TEST_F(CreatedUploadTest, AWriteToAnotherMapDoesNotWaitForALongUploadsCommit) {
  constexpr int64_t kTrees = 500'000;
  SqliteMapStore store(path_);
  store.CreateMap("b", "", "");
  std::atomic<bool> done{false};
  auto a = std::async(std::launch::async, [&] {
    auto upload = StagedCreate(store, "a", kTrees);
    const MapInfo info = upload->Commit();
    done = true;
    return info;
  });
  Clock::duration slowest{};
  int writes = 0;
  for (int64_t id = 1; !done; ++id) {
    const auto start = Clock::now();
    store.WriteTrees("b", {Chunk(id, 1)[0]}, WriteMode::kAppend);
    slowest = std::max(slowest, Clock::now() - start);
    ++writes;
  }
  EXPECT_EQ(a.get().tree_count, kTrees);
  EXPECT_GE(writes, 10);  // B was written all along A's upload
  std::printf("%d writes of map B during the upload of A, the slowest %.0f ms\n", writes,
              std::chrono::duration<double, std::milli>(slowest).count());
  EXPECT_EQ(store.GetMap("a").version, 2);
}

// A step-6 database as a killed step-6 server leaves it: a map, and an upload that was creating
// map 'half' with pending rows (valid_to = -upload id) and their block.
constexpr const char* kStep6Data = R"sql(
INSERT INTO maps (id, name, description, crs, version, tree_count, min_x, min_y, max_x, max_y,
  created_unix_ms, updated_unix_ms, confirmed_count)
  VALUES (1, 'kept', '', '', 2, 2, 1, 2, 3, 4, 1000, 2000, 2);
INSERT INTO map_versions VALUES (1, 1, 1000, 1, '', 0, 0, 0, 0, 0, 0, 0, 0);
INSERT INTO map_versions VALUES (1, 2, 2000, 2, '', 2, 2, 2, 0, 0, 0, 0, 0);
INSERT INTO trees (rowid, map_id, tree_id, valid_from, valid_to, x, y)
  VALUES (1, 1, 7, 2, 9223372036854775807, 1, 2), (2, 1, 8, 2, 9223372036854775807, 3, 4);
INSERT INTO tree_blocks VALUES (1, 1, 1, 1, 3, 2, 4, 1, 1, 2);
INSERT INTO maps (id, name, description, crs, version, tree_count, created_unix_ms,
  updated_unix_ms, creating_upload) VALUES (2, 'half', '', '', 1, 0, 3000, 3000, 1);
INSERT INTO uploads VALUES (1, 2, 1, 3, 4, 3000);
INSERT INTO trees (rowid, map_id, tree_id, valid_from, valid_to, x, y)
  VALUES (3, 2, 1, 0, -1, 5, 5), (4, 2, 2, 1, -1, 6, 6);
INSERT INTO tree_blocks VALUES (2, 2, 2, 5, 6, 5, 6, 2, 3, 4);
)sql";

TEST_F(CreatedUploadTest, MigratesAStep6DatabaseAndRemovesTheUploadAKilledServerLeft) {
  {
    sqlite::Database db(path_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, 1000);
    const std::vector<const char*>& all = sqlite::SchemaSteps();
    sqlite::MigrateSchema(db, std::vector<const char*>(all.begin(), all.begin() + 6));
    ASSERT_EQ(db.QueryInt64("PRAGMA user_version"), 6);
    db.Execute(kStep6Data);
  }
  {
    SqliteMapStore store(path_);
    EXPECT_EQ(store.ReadMap("kept").trees.size(), 2u);
    EXPECT_EQ(store.TreesInBox("kept", Extent{0, 0, 2, 3}).size(), 1u);
    EXPECT_THROW(store.GetMap("half"), StorageError);
    // The same command works now, on the step-7 path, and finds duplicates across chunks.
    auto upload = StagedCreate(store, "half", 2 * kChunk);
    std::vector<TreeRecord> again = Chunk(0, 2);
    again[0].id = 7 + kChunk;  // the id the server gave trees[kChunk + 6]
    try {
      upload->Append(again);
      FAIL() << "no error";
    } catch (const StorageError& e) {
      EXPECT_EQ(e.code(), StorageError::Code::kInvalidArgument);
      EXPECT_NE(std::string(e.what()).find("trees[20000].id 10007 duplicates trees[10006].id"),
                std::string::npos)
          << e.what();
    }
    EXPECT_EQ(StagedCreate(store, "half", kChunk)->Commit().tree_count, kChunk);
  }
  sqlite::Database db(path_, SQLITE_OPEN_READONLY, 1000);
  EXPECT_EQ(db.QueryInt64("PRAGMA user_version"), SqliteMapStore::kSchemaVersion);
  EXPECT_EQ(db.QueryInt64("SELECT COUNT(*) FROM uploads"), 0);
  EXPECT_EQ(db.QueryInt64("SELECT COUNT(*) FROM upload_chunks"), 0);
  EXPECT_EQ(db.QueryInt64("SELECT COUNT(*) FROM trees WHERE valid_to < 0"), 0);
  EXPECT_EQ(db.QueryInt64("SELECT COUNT(*) FROM trees"), 2 + kChunk);
  EXPECT_EQ(db.QueryInt64("SELECT COUNT(*) FROM tree_blocks"),
            1 + kChunk / static_cast<int64_t>(SqliteMapStore::kTreesPerBlock) + 1);
  sqlite::Statement check(db, "PRAGMA integrity_check");
  ASSERT_TRUE(check.Step());
  EXPECT_EQ(check.ColumnText(0), "ok");
}

}  // namespace
}  // namespace forestmap::storage
