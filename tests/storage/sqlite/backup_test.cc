// BackupDatabase: a copy made while another thread keeps replacing a map's trees holds exactly
// one complete version, passes integrity_check and opens as a map database.

#include "storage/backup.h"

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <thread>

#include "storage/sqlite/database.h"
#include "storage/sqlite/store.h"
#include "tests/storage/test_directory.h"

namespace forestmap::storage {
namespace {

constexpr int kTreesPerVersion = 5000;  // every write replaces the whole map with this many
constexpr int kBackups = 12;            // copies taken while the writer runs, at least
constexpr int kMaxBackups = 400;        // copies at most, waiting for one to overlap a commit
constexpr double kMarkerStep = 1e-3;    // m: dbh of every tree of write k is k * kMarkerStep

std::vector<TreeRecord> Version(int k) {
  std::vector<TreeRecord> trees(kTreesPerVersion);
  for (int i = 0; i < kTreesPerVersion; ++i) {
    trees[i].id = i + 1;
    trees[i].x = i % 100;
    trees[i].y = i / 100;
    trees[i].dbh = k * kMarkerStep;
  }
  return trees;
}

class BackupTest : public ::testing::Test {
 protected:
  std::string Path(const std::string& name) const { return dir_.File(name); }

  TestDirectory dir_;
};

std::string IntegrityCheck(const std::string& path) {
  sqlite::Database db(path, SQLITE_OPEN_READONLY, 1000);
  sqlite::Statement check(db, "PRAGMA integrity_check");
  return check.Step() ? check.ColumnText(0) : "no answer";
}

// The copy passes integrity_check, opens as a map database and holds one version, complete:
// every tree carries the marker of the same write, and that write is the version the map says
// it is at (version k+1 holds write k: creation is version 1).
void ExpectOneCompleteVersion(const std::string& copy) {
  SCOPED_TRACE(copy);
  EXPECT_EQ(IntegrityCheck(copy), "ok");
  SqliteMapStore backup(copy);
  const MapSnapshot snapshot = backup.ReadMap("m");
  ASSERT_EQ(snapshot.trees.size(), static_cast<size_t>(kTreesPerVersion));
  EXPECT_EQ(snapshot.info.tree_count, kTreesPerVersion);
  const double marker = *snapshot.trees.front().dbh;
  for (const TreeRecord& tree : snapshot.trees) ASSERT_EQ(*tree.dbh, marker);
  EXPECT_NEAR(marker / kMarkerStep, static_cast<double>(snapshot.info.version - 1), 1e-6);
}

TEST_F(BackupTest, CopiesOneCompleteVersionWhileWritesGoOn) {
  const std::string db_path = Path("maps.db");
  SqliteMapStore store(db_path);
  store.CreateMap("m", "", "");
  store.WriteTrees("m", Version(1), WriteMode::kReplace);

  std::atomic<bool> stop{false};
  std::atomic<int> writes{1};
  std::thread writer([&] {
    for (int k = 2; !stop; ++k) {
      store.WriteTrees("m", Version(k), WriteMode::kReplace);
      writes = k;
    }
  });
  // On a loaded machine the writer can commit only between the backups for a while (once: 0 of
  // 12 backups overlapped a commit, 5 writes in all): back up until a write committed during one.
  int overlapped = 0;  // backups during which at least one write committed
  int backups = 0;
  for (; backups < kMaxBackups && (backups < kBackups || overlapped == 0); ++backups) {
    const std::string copy = Path("copy" + std::to_string(backups) + ".db");
    const int before = writes;
    const BackupResult result = BackupDatabase(db_path, copy);
    overlapped += writes != before;
    EXPECT_EQ(result.integrity, "ok");
    EXPECT_GT(result.pages, 0);
    ExpectOneCompleteVersion(copy);
    std::filesystem::remove(copy);  // at most one copy on the disk
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  stop = true;
  writer.join();
  std::cout << overlapped << " of " << backups << " backups overlapped a commit, " << writes
            << " writes in all\n";
  EXPECT_GT(overlapped, 0) << "no write committed while a backup ran: the test proved nothing";
}

TEST_F(BackupTest, RefusesAnExistingTargetAndANonDatabase) {
  const std::string db_path = Path("maps.db");
  { SqliteMapStore store(db_path); }
  const std::string taken = Path("taken.db");
  { std::ofstream(taken) << "x"; }
  EXPECT_THROW(BackupDatabase(db_path, taken), StorageError);
  EXPECT_THROW(BackupDatabase(Path("missing.db"), Path("out.db")), StorageError);
  const std::string text = Path("notes.txt");
  { std::ofstream(text) << "this is not a database, not at all, it is a text file.\n"; }
  EXPECT_THROW(BackupDatabase(text, Path("out2.db")), StorageError);
  EXPECT_FALSE(std::filesystem::exists(Path("out2.db")));
}

}  // namespace
}  // namespace forestmap::storage
