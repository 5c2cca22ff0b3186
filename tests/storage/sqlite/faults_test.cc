// Issue 15, finding 7: faults of the database looked like bugs. A read-only database "served" and
// failed every write as an internal error, a full one too. Here: a read-only file is refused when
// opened (with its cause), a database moved away under a running store fails writes as
// kReadOnly, and a store at its size limit (--max-db-mb, PRAGMA max_page_count: what a full disk
// gives too) fails writes as kFull with the previous version intact; another program's database
// is refused unchanged.

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "storage/sqlite/database.h"
#include "storage/sqlite/store.h"

namespace forestmap::storage {
namespace {

constexpr uid_t kNobody = 65534;  // Debian's nobody / nogroup
using Code = StorageError::Code;

std::vector<TreeRecord> Trees(int count, int first_id) {
  std::vector<TreeRecord> trees(count);
  for (int i = 0; i < count; ++i) {
    trees[i].id = first_id + i;
    trees[i].x = i % 1000;
    trees[i].y = i / 1000;
    trees[i].dbh = 0.3;
    trees[i].attributes = {
        {"species", "Picea abies, a long attribute to take room " + std::to_string(i)}};
  }
  return trees;
}

class DbFaultsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() / ("db_faults_test_" + std::to_string(getpid()));
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override {
    std::filesystem::permissions(dir_, std::filesystem::perms::owner_all);
    std::filesystem::remove_all(dir_);
  }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }

  std::filesystem::path dir_;
};

// Opens `path` in a child process that runs as nobody when we are root (root writes any file
// whatever its mode, so only then does a read-only file mean anything). Returns "" when the
// store opened, else the code and message of the StorageError.
std::string OpenAsUnprivileged(const std::string& path) {
  int fds[2];
  if (pipe(fds) != 0) return "pipe failed";
  const pid_t child = fork();
  if (child == 0) {
    close(fds[0]);
    std::string result;
    if (geteuid() == 0 && (setgid(kNobody) != 0 || setuid(kNobody) != 0)) {
      result = "cannot become nobody";
    } else {
      try {
        SqliteMapStore store(path);
      } catch (const StorageError& e) {
        result = std::to_string(static_cast<int>(e.code())) + " " + e.what();
      }
    }
    if (write(fds[1], result.data(), result.size()) < 0) _exit(2);
    _exit(0);
  }
  close(fds[1]);
  std::string result;
  char buffer[512];
  ssize_t n = 0;
  while ((n = read(fds[0], buffer, sizeof buffer)) > 0) result.append(buffer, n);
  close(fds[0]);
  int status = 0;
  waitpid(child, &status, 0);
  return result;
}

TEST_F(DbFaultsTest, ReadOnlyFileIsRefusedWithItsCause) {
  const std::string path = Path("maps.db");
  {
    SqliteMapStore store(path);
    store.CreateMap("plot", "", "");
  }  // closed cleanly: no -wal / -shm left
  namespace fs = std::filesystem;
  // The directory stays writable (SQLite may create its -shm there); the file is read-only.
  fs::permissions(dir_, fs::perms::owner_all | fs::perms::others_read | fs::perms::others_exec |
                            fs::perms::others_write | fs::perms::group_all);
  fs::permissions(path, fs::perms::owner_read | fs::perms::group_read | fs::perms::others_read);
  const std::string result = OpenAsUnprivileged(path);
  const std::string read_only = std::to_string(static_cast<int>(StorageError::Code::kReadOnly));
  EXPECT_EQ(result.substr(0, read_only.size() + 1), read_only + " ") << result;
  EXPECT_NE(result.find("is read-only: the file is not writable by this user"), std::string::npos)
      << result;
}

TEST_F(DbFaultsTest, ReadOnlyDirectoryIsRefused) {
  const std::string path = Path("maps.db");
  { SqliteMapStore store(path); }
  namespace fs = std::filesystem;
  // The file is writable by everyone, its directory by nobody but root: no -wal can be made.
  fs::permissions(path, fs::perms::all);
  fs::permissions(dir_, fs::perms::owner_all | fs::perms::others_read | fs::perms::others_exec);
  const std::string result = OpenAsUnprivileged(path);
  EXPECT_FALSE(result.empty()) << "a database in a read-only directory was opened for writing";
  EXPECT_NE(result.find("is read-only: its directory"), std::string::npos) << result;
}

TEST(DbFaultCodesTest, SqliteResultsMapToFaultCodes) {
  EXPECT_EQ(sqlite::CodeForResult(SQLITE_FULL), Code::kFull);
  EXPECT_EQ(sqlite::CodeForResult(SQLITE_READONLY), Code::kReadOnly);
  EXPECT_EQ(sqlite::CodeForResult(SQLITE_READONLY_DBMOVED), Code::kReadOnly);
  EXPECT_EQ(sqlite::CodeForResult(SQLITE_READONLY_DIRECTORY), Code::kReadOnly);
  EXPECT_EQ(sqlite::CodeForResult(SQLITE_CORRUPT), Code::kCorrupt);
  EXPECT_EQ(sqlite::CodeForResult(SQLITE_NOTADB), Code::kCorrupt);
  EXPECT_EQ(sqlite::CodeForResult(SQLITE_BUSY), Code::kUnavailable);
  EXPECT_EQ(sqlite::CodeForResult(SQLITE_BUSY_SNAPSHOT), Code::kUnavailable);
  EXPECT_EQ(sqlite::CodeForResult(SQLITE_IOERR), Code::kInternal);
}

TEST_F(DbFaultsTest, ForeignBytesAreCorruptNotInternal) {
  const std::string path = Path("garbage.db");
  {
    std::ofstream out(path, std::ios::binary);
    for (int i = 0; i < 4096; ++i) out.put(static_cast<char>(i * 37 + 11));
  }
  try {
    SqliteMapStore store(path);
    ADD_FAILURE() << "a file of garbage opened as a database";
  } catch (const StorageError& e) {
    EXPECT_EQ(e.code(), StorageError::Code::kCorrupt) << e.what();
    EXPECT_NE(std::string(e.what()).find("not a database"), std::string::npos) << e.what();
  }
}

TEST_F(DbFaultsTest, SizeLimitFailsWritesAsFullAndKeepsThePreviousVersion) {
  SqliteMapStoreOptions options;
  options.max_db_mib = 1;
  const std::string path = Path("small.db");
  SqliteMapStore store(path, options);
  store.CreateMap("plot", "", "");
  const MapInfo before = store.WriteTrees("plot", Trees(100, 1), WriteMode::kAppend);
  try {
    store.WriteTrees("plot", Trees(20000, 1000), WriteMode::kAppend);
    ADD_FAILURE() << "20,000 trees fit into 1 MiB";
  } catch (const StorageError& e) {
    EXPECT_EQ(e.code(), StorageError::Code::kFull) << e.what();
    EXPECT_NE(std::string(e.what()).find("database or disk is full"), std::string::npos)
        << e.what();
  }
  const MapSnapshot after = store.ReadMap("plot");
  EXPECT_EQ(after.info.version, before.version);
  EXPECT_EQ(after.trees.size(), 100u);
  // Still writable within the limit, and the file kept to it (WAL checkpointed into it).
  EXPECT_EQ(store.WriteTrees("plot", Trees(10, 500), WriteMode::kAppend).tree_count, 110);
  EXPECT_LE(std::filesystem::file_size(path), 1u << 20);
}

TEST_F(DbFaultsTest, LockHeldPastTheBusyTimeoutIsUnavailable) {
  const std::string path = Path("locked.db");
  SqliteMapStoreOptions options;
  options.busy_timeout_ms = 100;  // the store's retries end after 100 ms
  SqliteMapStore store(path, options);
  store.CreateMap("plot", "", "");
  sqlite::Database other(path, SQLITE_OPEN_READWRITE, 0);  // another process, holding the lock
  other.Execute("BEGIN IMMEDIATE");
  try {
    store.WriteTrees("plot", Trees(10, 1), WriteMode::kAppend);
    ADD_FAILURE() << "a write went through a held lock";
  } catch (const StorageError& e) {
    EXPECT_EQ(e.code(), StorageError::Code::kUnavailable) << e.what();
  }
  other.Execute("ROLLBACK");
  EXPECT_EQ(store.WriteTrees("plot", Trees(10, 1), WriteMode::kAppend).tree_count, 10);
}

TEST_F(DbFaultsTest, NegativeSizeLimitIsRefused) {
  SqliteMapStoreOptions options;
  options.max_db_mib = -1;
  EXPECT_THROW(SqliteMapStore(":memory:", options), StorageError);
}

// An unrelated SQLite file was migrated without a word.
TEST(OpenFaultsTest, DatabaseOfAnotherProgramIsRefusedUnchanged) {
  const std::filesystem::path path = std::filesystem::temp_directory_path() /
                                     ("forestmap_foreign_" + std::to_string(getpid()) + ".db");
  std::filesystem::remove(path);
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(
      sqlite3_exec(db, "CREATE TABLE invoices (id INTEGER, total REAL)", nullptr, nullptr, nullptr),
      SQLITE_OK);
  sqlite3_close(db);
  try {
    SqliteMapStore store(path.string());
    ADD_FAILURE() << "a foreign database was opened";
  } catch (const StorageError& e) {
    EXPECT_EQ(e.code(), StorageError::Code::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("is not a ForestMap database (it holds tables invoices"),
              std::string::npos)
        << e.what();
  }
  // Unchanged: still no ForestMap table, still schema version 0.
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  sqlite3_stmt* stmt = nullptr;
  sqlite3_prepare_v2(db, "SELECT COUNT(*) FROM sqlite_master WHERE name = 'maps'", -1, &stmt,
                     nullptr);
  ASSERT_EQ(sqlite3_step(stmt), SQLITE_ROW);
  EXPECT_EQ(sqlite3_column_int(stmt, 0), 0);
  sqlite3_finalize(stmt);
  sqlite3_close(db);
  // A new file and a ForestMap database still open.
  std::filesystem::remove(path);
  { SqliteMapStore fresh(path.string()); }
  { SqliteMapStore again(path.string()); }
  for (const char* suffix : {"", "-wal", "-shm"}) std::filesystem::remove(path.string() + suffix);
}

}  // namespace
}  // namespace forestmap::storage
