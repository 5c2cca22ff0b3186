// Issue 15, finding 7: an unrelated SQLite file was migrated without a word.

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "storage/sqlite/store.h"

namespace forestmap::storage {
namespace {

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
