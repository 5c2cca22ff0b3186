// TokenStore: tokens are stored hashed, found by their secret, scoped by map pattern and role,
// and revoked tokens stop working but keep the server closed.

#include "storage/token_store.h"

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include <filesystem>
#include <set>
#include <string>

#include "storage/sqlite/database.h"
#include "storage/sqlite/store.h"

namespace forestmap::storage {
namespace {

TEST(Sha256Hex, MatchesTheStandardTestVectors) {
  // FIPS 180-2 examples.
  EXPECT_EQ(Sha256Hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(Sha256Hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
}

TEST(TokenStore, CreateFindRevoke) {
  TokenStore tokens(":memory:");
  EXPECT_FALSE(tokens.AnyToken());
  const NewToken token = tokens.Create("plot-*", Role::kWrite, "drone 7");
  EXPECT_TRUE(token.secret.starts_with("fmt_"));
  EXPECT_EQ(token.secret.size(), 4u + 64u);
  EXPECT_TRUE(tokens.AnyToken());
  const std::optional<TokenRecord> found = tokens.Find(token.secret);
  ASSERT_TRUE(found.has_value());
  EXPECT_EQ(found->id, token.record.id);
  EXPECT_EQ(found->map_pattern, "plot-*");
  EXPECT_EQ(found->role, Role::kWrite);
  EXPECT_EQ(found->note, "drone 7");
  std::string longer = token.secret;
  longer.push_back('0');
  EXPECT_FALSE(tokens.Find(longer).has_value());
  EXPECT_FALSE(tokens.Find("").has_value());

  EXPECT_TRUE(tokens.Revoke(token.record.id));
  EXPECT_FALSE(tokens.Revoke(token.record.id));  // already revoked
  EXPECT_FALSE(tokens.Revoke(999));
  EXPECT_FALSE(tokens.Find(token.secret).has_value());
  EXPECT_TRUE(tokens.AnyToken());  // deny by default stays in force
  const std::vector<TokenRecord> all = tokens.List();
  ASSERT_EQ(all.size(), 1u);
  EXPECT_TRUE(all[0].revoked());
}

TEST(TokenStore, SecretsAreRandomAndNeverStored) {
  std::string name = "token_store_test_";
  name.append(std::to_string(getpid()));
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "maps.db").string();
  std::set<std::string> secrets;
  {
    TokenStore tokens(path);
    for (int i = 0; i < 20; ++i) secrets.insert(tokens.Create("*", Role::kRead).secret);
  }
  EXPECT_EQ(secrets.size(), 20u);
  sqlite::Database db(path, SQLITE_OPEN_READONLY, 1000);
  sqlite::Statement rows(db, "SELECT secret_sha256 FROM access_tokens");
  int count = 0;
  while (rows.Step()) {
    const std::string stored = rows.ColumnText(0);
    EXPECT_EQ(secrets.count(stored), 0u);
    bool matches_a_hash = false;
    for (const std::string& secret : secrets) matches_a_hash |= Sha256Hex(secret) == stored;
    EXPECT_TRUE(matches_a_hash);
    ++count;
  }
  EXPECT_EQ(count, 20);
  // The same file serves as the map database: the schema is the map store's.
  EXPECT_EQ(db.QueryInt64("PRAGMA user_version"), SqliteMapStore::kSchemaVersion);
  std::filesystem::remove_all(dir);
}

TokenRecord Grant(Role role, const char* pattern) {
  TokenRecord token;
  token.role = role;
  token.map_pattern = pattern;
  return token;
}

TEST(TokenRecord, AllowsByRoleOrderAndMapPattern) {
  const TokenRecord plots = Grant(Role::kWrite, "plot-*");
  EXPECT_TRUE(plots.Allows(Role::kRead, "plot-1"));
  EXPECT_TRUE(plots.Allows(Role::kWrite, "plot-1"));
  EXPECT_FALSE(plots.Allows(Role::kAdmin, "plot-1"));
  EXPECT_FALSE(plots.Allows(Role::kRead, "other"));
  EXPECT_FALSE(plots.Allows(Role::kRead, "xplot-1"));
  EXPECT_TRUE(Grant(Role::kWrite, "*").Allows(Role::kWrite, "anything"));
  TokenRecord exact = Grant(Role::kRead, "exact");
  EXPECT_TRUE(exact.Allows(Role::kRead, "exact"));
  EXPECT_FALSE(exact.Allows(Role::kRead, "exact2"));
  exact.revoked_unix_ms = 1;
  EXPECT_FALSE(exact.Allows(Role::kRead, "exact"));
}

TEST(TokenStore, RejectsAnEmptyPattern) {
  TokenStore tokens(":memory:");
  EXPECT_THROW(tokens.Create("", Role::kRead), StorageError);
  EXPECT_EQ(ParseRole("admin"), Role::kAdmin);
  EXPECT_FALSE(ParseRole("root").has_value());
}

}  // namespace
}  // namespace forestmap::storage
