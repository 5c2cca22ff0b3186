// Issue 15 on PostgreSQL: a database that refuses writes (default_transaction_read_only, as on a
// standby) fails writes as kReadOnly instead of an internal error. Runs on the throwaway cluster
// of tests/pg_fixture.h. (Tokens in the PostgreSQL database: tests/storage/token_store_test.cc.)

#include <gtest/gtest.h>

#include <string>

#include "storage/postgres/connection.h"
#include "storage/postgres/store.h"
#include "tests/pg_fixture.h"

namespace forestmap::storage {
namespace {

// Runs `sql` on the database of `url` as its owner, from its own connection.
void Admin(const std::string& url, const std::string& sql) {
  pg::Connection admin(url);
  admin.ExecScript(sql.c_str());
}

std::string DatabaseName(const std::string& url) { return url.substr(url.rfind('/') + 1); }

TEST(PostgresFaults, DatabaseTurnedReadOnlyFailsWritesAsReadOnly) {
  testing::TestDatabase database;
  PostgresMapStore store(database.url());
  store.CreateMap("plot", "", "");
  // The database turns read-only under the running store (as a primary demoted to a standby):
  // new sessions are read-only, and the store's open sessions are cut.
  Admin(database.url(), "ALTER DATABASE " + DatabaseName(database.url()) +
                            " SET default_transaction_read_only = on");
  Admin(database.url(),
        "SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE datname = current_database() "
        "AND pid <> pg_backend_pid()");
  // The cut session answers kUnavailable (retry later) until the pool has a fresh one.
  int unavailable = 0;
  for (int attempt = 0; attempt < 3; ++attempt) {
    try {
      store.CreateMap("other", "", "");
      ADD_FAILURE() << "a read-only database took a write";
      break;
    } catch (const StorageError& e) {
      if (e.code() == StorageError::Code::kUnavailable) {
        ++unavailable;
        continue;
      }
      EXPECT_EQ(e.code(), StorageError::Code::kReadOnly) << e.what();
      EXPECT_NE(std::string(e.what()).find("read-only transaction"), std::string::npos) << e.what();
      break;
    }
  }
  EXPECT_LE(unavailable, 1);
  EXPECT_EQ(store.GetMap("plot").name, "plot");  // reads go on
  // A store opened on it now is refused as read-only, before serving anything.
  try {
    PostgresMapStore again(database.url());
    ADD_FAILURE() << "a read-only database was opened for writing";
  } catch (const StorageError& e) {
    EXPECT_EQ(e.code(), StorageError::Code::kReadOnly) << e.what();
  }
}

}  // namespace
}  // namespace forestmap::storage
