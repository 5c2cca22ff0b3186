#pragma once
// Access tokens of forestmapd, kept in the server's database: the SQLite file (table
// access_tokens, see storage/sqlite/schema.cc) or, for a postgresql:// --db, the PostgreSQL
// database (table access_tokens, made on first use: storage/postgres/tokens.cc). A token
// grants one role on the maps matching a pattern: a map name, a glob ("plot-*", fnmatch syntax) or
// "*" for every map. Roles are ordered: admin includes write, write includes read. Only the SHA-256
// of the secret is stored: the secret is shown once, by Create, and cannot be recovered from the
// database.
//
// Separate from MapStore on purpose: tokens are not maps, and MapStore's interface stays
// about maps.
//
// Thread-safety: every method may be called from many threads at once (SQLite: one connection,
// one mutex; PostgreSQL: a small connection pool; each call is one short statement). Other
// processes (`forestmapd token ...`, replicas) may change the table while a server reads it:
// changes are seen by the next call.

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace forestmap::storage {

class TokenBackend;  // storage/token_backend.h

enum class Role { kRead = 1, kWrite = 2, kAdmin = 3 };

const char* RoleName(Role role);                       // "read", "write", "admin"
std::optional<Role> ParseRole(std::string_view name);  // nullopt for anything else

struct TokenRecord {
  int64_t id = 0;
  std::string map_pattern;  // map name, glob, or "*"
  Role role = Role::kRead;
  std::string note;             // free text given at creation (who / what it is for)
  int64_t created_unix_ms = 0;  // ms since 1970
  int64_t revoked_unix_ms = 0;  // ms since 1970; 0 while valid
  int64_t expires_unix_ms = 0;  // ms since 1970; 0: never expires
  bool revoked() const { return revoked_unix_ms != 0; }
  bool expired(int64_t now_unix_ms) const {
    return expires_unix_ms != 0 && now_unix_ms >= expires_unix_ms;
  }
  // True when this (valid) token grants at least `needed` on map `map`.
  bool Allows(Role needed, std::string_view map) const;
};

struct NewToken {
  TokenRecord record;
  std::string secret;  // "fmt_" + 64 hex digits; shown once, stored only as its SHA-256
};

// The secret of an Authorization value "Bearer <secret>" (gRPC metadata or an HTTP header): the
// scheme in any case (RFC 7235 section 2.1), one or more spaces before the secret (RFC 6750
// section 2.1). Empty when malformed.
std::string_view BearerSecret(std::string_view authorization);

// Lowercase hex SHA-256 of `data` (OpenSSL libcrypto).
std::string Sha256Hex(std::string_view data);

class TokenStore {
 public:
  // Opens (creating and migrating if needed, like SqliteMapStore) the database at `path`;
  // ":memory:" gives a private one for tests; a postgresql:// URI the tokens of that PostgreSQL
  // database. Throws StorageError.
  explicit TokenStore(const std::string& path, int busy_timeout_ms = 5000);
  ~TokenStore();
  TokenStore(const TokenStore&) = delete;
  TokenStore& operator=(const TokenStore&) = delete;

  // A token valid until `expires_unix_ms` (ms since 1970; 0: no expiry). Throws StorageError
  // kInvalidArgument for an empty pattern, one longer than 256 bytes, or an expiry not in the
  // future.
  NewToken Create(const std::string& map_pattern, Role role, const std::string& note = "",
                  int64_t expires_unix_ms = 0);
  std::vector<TokenRecord> List();  // by id, revoked ones included
  // False when there is no such token or it was already revoked.
  bool Revoke(int64_t id);
  // The valid token whose secret is `secret`, if any (revoked and expired tokens are not found).
  std::optional<TokenRecord> Find(std::string_view secret);
  // True once any token was created (revoked ones count): the server then denies by default.
  bool AnyToken();

 private:
  std::unique_ptr<TokenBackend> backend_;
  std::atomic<bool> any_token_{false};  // AnyToken() was true once
};

}  // namespace forestmap::storage
