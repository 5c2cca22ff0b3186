// Access tokens in a SQLite file: a token store on a new file makes the map schema, so that the
// same file then serves as the server's map database.

#include <gtest/gtest.h>
#include <sqlite3.h>

#include <string>

#include "storage/sqlite/database.h"
#include "storage/sqlite/store.h"
#include "storage/token_store.h"
#include "tests/storage/test_directory.h"

namespace forestmap::storage {
namespace {

TEST(SqliteTokens, ANewFileGetsTheMapSchema) {
  const TestDirectory dir;
  const std::string path = dir.File("maps.db");
  {
    TokenStore tokens(path);
    tokens.Create("*", Role::kRead);
  }
  sqlite::Database db(path, SQLITE_OPEN_READONLY, 1000);
  EXPECT_EQ(db.QueryInt64("PRAGMA user_version"), SqliteMapStore::kSchemaVersion);
  EXPECT_EQ(db.QueryInt64("SELECT COUNT(*) FROM access_tokens"), 1);
  SqliteMapStore maps(path);
  EXPECT_TRUE(maps.ListMaps().empty());
}

}  // namespace
}  // namespace forestmap::storage
