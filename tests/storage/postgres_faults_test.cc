// Issue 15 on PostgreSQL: bearer tokens live in the PostgreSQL database too (a PG-backed server
// used to stay open whatever tokens were made), shared by every replica, stored hashed; and a
// database that refuses writes (default_transaction_read_only, as on a standby) fails writes as
// kReadOnly instead of an internal error. Runs on the throwaway cluster of tests/pg_fixture.h.

#include <gtest/gtest.h>

#include <string>

#include "storage/postgres/connection.h"
#include "storage/postgres/store.h"
#include "storage/token_store.h"
#include "tests/pg_fixture.h"

namespace forestmap::storage {
namespace {

TEST(PostgresTokens, CreateFindRevokeListAcrossReplicas) {
  testing::TestDatabase database;
  TokenStore tokens(database.url());
  TokenStore replica(database.url());  // another forestmapd on the same database
  EXPECT_FALSE(tokens.AnyToken());
  EXPECT_FALSE(replica.AnyToken());
  const NewToken writer = tokens.Create("plot-*", Role::kWrite, "drone 7");
  const NewToken admin = tokens.Create("*", Role::kAdmin);
  EXPECT_TRUE(writer.secret.starts_with("fmt_"));
  EXPECT_NE(writer.record.id, admin.record.id);
  EXPECT_TRUE(replica.AnyToken());  // deny by default on every replica
  const std::optional<TokenRecord> found = replica.Find(writer.secret);
  ASSERT_TRUE(found.has_value());
  EXPECT_EQ(found->id, writer.record.id);
  EXPECT_EQ(found->map_pattern, "plot-*");
  EXPECT_EQ(found->role, Role::kWrite);
  EXPECT_EQ(found->note, "drone 7");
  EXPECT_EQ(found->created_unix_ms, writer.record.created_unix_ms);
  EXPECT_TRUE(found->Allows(Role::kWrite, "plot-3"));
  EXPECT_FALSE(found->Allows(Role::kAdmin, "plot-3"));
  EXPECT_FALSE(replica.Find(writer.secret + "0").has_value());
  EXPECT_FALSE(replica.Find("").has_value());

  EXPECT_TRUE(replica.Revoke(writer.record.id));
  EXPECT_FALSE(tokens.Revoke(writer.record.id));  // already revoked
  EXPECT_FALSE(tokens.Revoke(999));
  EXPECT_FALSE(tokens.Find(writer.secret).has_value());
  EXPECT_TRUE(tokens.Find(admin.secret).has_value());
  const std::vector<TokenRecord> all = tokens.List();
  ASSERT_EQ(all.size(), 2u);
  EXPECT_EQ(all[0].id, writer.record.id);
  EXPECT_TRUE(all[0].revoked());
  EXPECT_FALSE(all[1].revoked());
  // Only hashes are stored.
  pg::Connection conn(database.url());
  const pg::Result rows = conn.Exec("SELECT secret_sha256 FROM access_tokens ORDER BY id");
  ASSERT_EQ(rows.rows(), 2);
  EXPECT_EQ(rows.Text(0, 0), Sha256Hex(writer.secret));
  EXPECT_EQ(rows.Text(1, 0), Sha256Hex(admin.secret));
}

TEST(PostgresTokens, TokensAndMapsShareOneDatabase) {
  testing::TestDatabase database;
  PostgresMapStore maps(database.url());
  TokenStore tokens(database.url());
  maps.CreateMap("plot", "", "");
  tokens.Create("plot", Role::kRead);
  EXPECT_EQ(maps.ListMaps().size(), 1u);
  EXPECT_EQ(tokens.List().size(), 1u);
  TokenStore again(database.url());  // the table exists: opening again changes nothing
  EXPECT_EQ(again.List().size(), 1u);
}

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
