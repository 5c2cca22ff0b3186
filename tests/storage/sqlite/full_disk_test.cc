// A full database can be freed and opened again. A store at its size limit (PRAGMA max_page_count,
// --max-db-mb) or on a file system with no space left used to fail DeleteMap and PruneVersions as
// kFull too (nothing could free room), and could not be opened again. Here: delete and prune
// succeed on a full database and free room for later writes, and a full database opens, serves
// reads and fails writes as kFull, with the size limit and on a real full tmpfs (mounted in a
// private mount namespace of a child process: the test runs as root, as CI does).

#include <gtest/gtest.h>
#include <sys/mount.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "storage/sqlite/store.h"
#include "storage/staged_writes.h"
#include "storage/write_request.h"

namespace forestmap::storage {
namespace {

using Code = StorageError::Code;

std::vector<TreeRecord> FillerTrees(int count, int first_id) {
  std::vector<TreeRecord> trees(count);
  for (int i = 0; i < count; ++i) {
    trees[i].id = first_id + i;
    trees[i].x = i % 100;
    trees[i].y = i / 100;
    trees[i].dbh = 0.3;
    trees[i].attributes = {{"species", "Picea abies, room taken " + std::to_string(i)}};
  }
  return trees;
}

// Writes versions of `name` (each replacing all its trees, so older versions hold rows only they
// keep) until the database is full, to its last page: batches of 500 trees until one fails, then
// smaller ones down to a single tree. Returns how many versions were written. Fails the test when
// a write fails other than as kFull.
int FillWithHistory(MapStore& store, const std::string& name) {
  int written = 0;
  for (const int batch : {500, 50, 5, 1}) {
    for (;; ++written) {
      try {
        store.WriteTrees(name, FillerTrees(batch, 1), WriteMode::kReplace);
      } catch (const StorageError& e) {
        EXPECT_EQ(e.code(), Code::kFull) << e.what();
        break;
      }
      if (written > 100000) {
        ADD_FAILURE() << "the database never filled";
        return written;
      }
    }
  }
  return written;
}

// Runs `write` as the server does: with a request id, whose answer is stored with the write.
template <typename Write>
void WithRequestId(const std::string& id, const std::string& rpc, const Write& write) {
  WriteRequest request;
  request.id = id;
  request.rpc = rpc;
  request.encode = [](const MapInfo& info) { return info.name + std::string(64, 'x'); };
  const WriteRequestScope scope(request);
  write();
}

// Fills the store, then deletes and prunes on the full database: both succeed, and free room
// for the writes that failed before.
void ExpectDeleteAndPruneFreeAFullDatabase(MapStore& store) {
  store.CreateMap("kept", "", "");
  store.WriteTrees("kept", FillerTrees(100, 1), WriteMode::kAppend);
  store.CreateMap("history", "", "");
  store.CreateMap("doomed", "", "");
  store.WriteTrees("doomed", FillerTrees(2000, 1), WriteMode::kAppend);
  ASSERT_GT(FillWithHistory(store, "history"), 3);

  PruneResult pruned;
  WithRequestId("prune-1", "PruneVersions",
                [&] { pruned = store.PruneVersions("history", /*keep=*/1); });
  EXPECT_GT(pruned.tree_rows_removed, 0);
  EXPECT_EQ(store.ListVersions("history", 0).size(), 1u);
  // The room pruning freed takes a write that did not fit.
  EXPECT_EQ(store.WriteTrees("kept", FillerTrees(500, 1000), WriteMode::kAppend).tree_count, 600);

  ASSERT_GT(FillWithHistory(store, "history"), 0);
  WithRequestId("delete-1", "DeleteMap", [&] { store.DeleteMap("doomed"); });
  EXPECT_THROW(store.GetMap("doomed"), StorageError);
  EXPECT_EQ(store.WriteTrees("kept", FillerTrees(500, 2000), WriteMode::kAppend).tree_count, 1100);
  EXPECT_EQ(store.ReadMap("kept").trees.size(), 1100u);
}

// A full database opened again: reads are served, a write fails as kFull, a delete succeeds.
void ExpectFullDatabaseOpens(const std::string& path, const SqliteMapStoreOptions& options) {
  SqliteMapStore store(path, options);
  EXPECT_EQ(store.ReadMap("kept").trees.size(), 100u);
  EXPECT_EQ(store.ListMaps().size(), 3u);
  try {
    store.WriteTrees("kept", FillerTrees(2000, 1000), WriteMode::kAppend);
    ADD_FAILURE() << "a write fitted into a full database";
  } catch (const StorageError& e) {
    EXPECT_EQ(e.code(), Code::kFull) << e.what();
  }
  store.DeleteMap("doomed");
  EXPECT_EQ(store.WriteTrees("kept", FillerTrees(500, 1000), WriteMode::kAppend).tree_count, 600);
}

class FullDiskTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() / ("full_disk_test_" + std::to_string(getpid()));
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }

  std::filesystem::path dir_;
};

TEST_F(FullDiskTest, AtTheSizeLimitDeleteAndPruneFreeRoom) {
  SqliteMapStoreOptions options;
  options.max_db_mib = 2;
  SqliteMapStore store(Path("limit.db"), options);
  ExpectDeleteAndPruneFreeAFullDatabase(store);
}

TEST_F(FullDiskTest, AtTheSizeLimitTheDatabaseOpensAgain) {
  SqliteMapStoreOptions options;
  options.max_db_mib = 2;
  const std::string path = Path("reopen.db");
  {
    SqliteMapStore store(path, options);
    store.CreateMap("kept", "", "");
    store.WriteTrees("kept", FillerTrees(100, 1), WriteMode::kAppend);
    store.CreateMap("doomed", "", "");
    store.WriteTrees("doomed", FillerTrees(2000, 1), WriteMode::kAppend);
    store.CreateMap("history", "", "");
    ASSERT_GT(FillWithHistory(store, "history"), 3);
  }
  ExpectFullDatabaseOpens(path, options);
}

// Runs `body` in a child process with a private mount namespace in which `dir` is a tmpfs of
// `mib` MiB: a real file system that runs out of space. Returns the child's exit status; -1
// when the namespace or the mount is not allowed (not root, no CAP_SYS_ADMIN).
int WithFullTmpfs(const std::filesystem::path& dir, int mib, const std::function<int()>& body) {
  const pid_t child = fork();
  if (child == 0) {
    if (unshare(CLONE_NEWNS) != 0) _exit(100);
    if (mount(nullptr, "/", nullptr, MS_REC | MS_PRIVATE, nullptr) != 0) _exit(100);
    const std::string size = "size=" + std::to_string(mib) + "m";
    if (mount("tmpfs", dir.c_str(), "tmpfs", 0, size.c_str()) != 0) _exit(100);
    try {
      _exit(body());
    } catch (const std::exception& e) {
      ADD_FAILURE() << e.what();
      _exit(1);
    }
  }
  int status = 0;
  waitpid(child, &status, 0);
  if (!WIFEXITED(status)) return 99;
  return WEXITSTATUS(status) == 100 ? -1 : WEXITSTATUS(status);
}

// Writes `path` until the file system has no byte left, then gives `leave_bytes` back.
void FillFileSystem(const std::filesystem::path& path, uintmax_t leave_bytes) {
  std::FILE* file = std::fopen(path.c_str(), "wb");
  ASSERT_NE(file, nullptr);
  std::setvbuf(file, nullptr, _IONBF, 0);
  const std::string block(4096, 'x');
  while (std::fwrite(block.data(), 1, block.size(), file) == block.size()) {
  }
  while (std::fwrite(block.data(), 1, 1, file) == 1) {
  }
  std::fclose(file);
  std::filesystem::resize_file(path, std::filesystem::file_size(path) - leave_bytes);
}

// Stages 20,000 trees of an upload into map "kept" of `path` in a process that stops before the
// upload commits or ends: its rows stay until the database is opened again.
void AbandonAnUpload(const std::string& path) {
  const pid_t child = fork();
  if (child == 0) {
    SqliteMapStore store(path);
    const std::unique_ptr<TreeUpload> upload = store.BeginUpload("kept", UploadPlan{});
    upload->Append(FillerTrees(20000, 10000));
    _exit(0);
  }
  int status = 0;
  waitpid(child, &status, 0);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
}

TEST_F(FullDiskTest, OnAFullFileSystemDeletePruneAndOpenWork) {
  const std::filesystem::path mount_point = dir_ / "tmpfs";
  std::filesystem::create_directories(mount_point);
  const std::string path = (mount_point / "maps.db").string();
  const int status = WithFullTmpfs(mount_point, 8, [&] {
    SqliteMapStoreOptions options;
    options.reserve_mib = 2;
    {
      SqliteMapStore store(path, options);
      ExpectDeleteAndPruneFreeAFullDatabase(store);
      // Full again, then the store closes and opens on the full file system.
      store.CreateMap("doomed", "", "");
      store.WriteTrees("doomed", FillerTrees(2000, 1), WriteMode::kAppend);
      store.WriteTrees("kept", FillerTrees(1000, 1), WriteMode::kReplace);
      store.PruneVersions("kept", 1);
      store.WriteTrees("kept", FillerTrees(100, 1), WriteMode::kReplace);
      FillWithHistory(store, "history");
    }
    // Closing gave the write-ahead log's room back to the file system: fill it again, leaving
    // 256 KiB, room for a delete's log but not for the 2,000 trees a write then tries.
    FillFileSystem(mount_point / "filler", /*leave_bytes=*/256 << 10);
    ExpectFullDatabaseOpens(path, options);
    std::filesystem::remove(mount_point / "filler");
    // A start on a full disk whose reserve was used up: an upload abandoned by a process that
    // stopped has rows to remove and the file system has room for the -shm index but not for
    // that removal. The store opens all the same, says so, serves reads and fails writes as
    // kFull.
    std::filesystem::remove(path + "-reserve");
    AbandonAnUpload(path);
    FillFileSystem(mount_point / "other-file", /*leave_bytes=*/160 << 10);
    options.reserve_mib = 0;
    SqliteMapStore store(path, options);
    EXPECT_NE(store.OpenWarning().find("database full: the removal of abandoned uploads skipped"),
              std::string::npos)
        << store.OpenWarning();
    EXPECT_EQ(store.ReadMap("kept").trees.size(), 600u);
    EXPECT_EQ(store.ListMaps().size(), 2u);
    try {
      store.WriteTrees("kept", FillerTrees(2000, 5000), WriteMode::kAppend);
      ADD_FAILURE() << "a write fitted into a full file system";
    } catch (const StorageError& e) {
      EXPECT_EQ(e.code(), Code::kFull) << e.what();
    }
    return ::testing::Test::HasFailure() ? 1 : 0;
  });
  if (status == -1) {
    ADD_FAILURE() << "cannot mount a tmpfs in a private mount namespace (needs root)";
    return;
  }
  EXPECT_EQ(status, 0) << "the failures above were in the child process";
}

}  // namespace
}  // namespace forestmap::storage
