// TokenStore on every backend: tokens are stored hashed, found by their secret, scoped by map
// pattern and role, shared by every store on the database (replicas), and revoked or expired
// tokens stop working but keep the server closed.

#include "storage/token_store.h"

#include <gtest/gtest.h>

#include <chrono>
#include <limits>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "tests/storage/store_backends.h"

namespace forestmap::storage {
namespace {

TEST(Sha256Hex, MatchesTheStandardTestVectors) {
  // FIPS 180-2 examples.
  EXPECT_EQ(Sha256Hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(Sha256Hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
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

class TokenStoreTest : public ::testing::TestWithParam<Backend> {
 protected:
  TestStore database_{GetParam()};  // the map store's database: tokens live beside the maps
};
INSTANTIATE_TEST_SUITE_P(Backends, TokenStoreTest, kAllBackends, BackendName);

TEST_P(TokenStoreTest, CreateFindRevoke) {
  TokenStore tokens(database_.db());
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

TEST(TokenRecord, ExpiresAtItsExpiry) {
  TokenRecord token = Grant(Role::kRead, "*");
  EXPECT_FALSE(token.expired(std::numeric_limits<int64_t>::max()));  // 0: never
  token.expires_unix_ms = 1000;
  EXPECT_FALSE(token.expired(999));
  EXPECT_TRUE(token.expired(1000));
}

TEST_P(TokenStoreTest, ExpiredTokensAreNotFoundButListed) {
  TokenStore tokens(database_.db());
  const auto now_ms = [] {
    return std::chrono::duration_cast<std::chrono::milliseconds>(
               std::chrono::system_clock::now().time_since_epoch())
        .count();
  };
  EXPECT_THROW(tokens.Create("*", Role::kRead, "", now_ms() - 1), StorageError);
  EXPECT_THROW(tokens.Create("*", Role::kRead, "", -5), StorageError);

  const int64_t in_an_hour = now_ms() + 3'600'000;
  const NewToken lasting = tokens.Create("*", Role::kRead, "a day's work", in_an_hour);
  const std::optional<TokenRecord> found = tokens.Find(lasting.secret);
  ASSERT_TRUE(found.has_value());
  EXPECT_EQ(found->expires_unix_ms, in_an_hour);

  const NewToken brief = tokens.Create("*", Role::kRead, "brief", now_ms() + 20);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_FALSE(tokens.Find(brief.secret).has_value());
  EXPECT_TRUE(tokens.Find(lasting.secret).has_value());
  const std::vector<TokenRecord> all = tokens.List();
  ASSERT_EQ(all.size(), 2u);
  EXPECT_EQ(all[0].expires_unix_ms, in_an_hour);
  EXPECT_FALSE(all[1].revoked());  // expired, not revoked
  EXPECT_TRUE(all[1].expired(now_ms()));
  EXPECT_EQ(tokens.Create("*", Role::kRead).record.expires_unix_ms, 0);  // no expiry
  EXPECT_EQ(tokens.List().back().expires_unix_ms, 0);
}

TEST_P(TokenStoreTest, RejectsAnEmptyPattern) {
  TokenStore tokens(database_.db());
  EXPECT_THROW(tokens.Create("", Role::kRead), StorageError);
  EXPECT_EQ(ParseRole("admin"), Role::kAdmin);
  EXPECT_FALSE(ParseRole("root").has_value());
}

// ---- Databases that several stores share ----

class SharedTokenStoreTest : public ::testing::TestWithParam<Backend> {
 protected:
  TestStore database_{GetParam()};
};
INSTANTIATE_TEST_SUITE_P(Backends, SharedTokenStoreTest, kSharedBackends, BackendName);

TEST_P(SharedTokenStoreTest, SecretsAreRandomAndNeverStored) {
  std::set<std::string> secrets;
  {
    TokenStore tokens(database_.db());
    for (int i = 0; i < 20; ++i) secrets.insert(tokens.Create("*", Role::kRead).secret);
  }
  EXPECT_EQ(secrets.size(), 20u);
  const std::vector<std::string> stored =
      database_.Column("SELECT secret_sha256 FROM access_tokens");
  for (const std::string& hash : stored) {
    EXPECT_EQ(secrets.count(hash), 0u);
    bool matches_a_hash = false;
    for (const std::string& secret : secrets) matches_a_hash |= Sha256Hex(secret) == hash;
    EXPECT_TRUE(matches_a_hash);
  }
  EXPECT_EQ(stored.size(), 20u);
}

TEST_P(SharedTokenStoreTest, CreateFindRevokeListAcrossReplicas) {
  TokenStore tokens(database_.db());
  TokenStore replica(database_.db());  // another forestmapd on the same database
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
  EXPECT_EQ(database_.Column("SELECT secret_sha256 FROM access_tokens ORDER BY id"),
            (std::vector<std::string>{Sha256Hex(writer.secret), Sha256Hex(admin.secret)}));
}

TEST_P(SharedTokenStoreTest, TokensAndMapsShareOneDatabase) {
  MapStore& maps = *database_;
  TokenStore tokens(database_.db());
  maps.CreateMap("plot", "", "");
  tokens.Create("plot", Role::kRead);
  EXPECT_EQ(maps.ListMaps().size(), 1u);
  EXPECT_EQ(tokens.List().size(), 1u);
  TokenStore again(database_.db());  // the table exists: opening again changes nothing
  EXPECT_EQ(again.List().size(), 1u);
}

}  // namespace
}  // namespace forestmap::storage
