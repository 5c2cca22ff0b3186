#include "storage/token_store.h"

#include <fnmatch.h>
#include <openssl/evp.h>
#include <openssl/rand.h>
#include <sqlite3.h>

#include <array>
#include <cstdio>
#include <mutex>

#include "storage/postgres_map_store.h"
#include "storage/sqlite.h"
#include "storage/sqlite_map_store_internal.h"
#include "storage/token_backend.h"

namespace forestmap::storage {
namespace {

constexpr size_t kSecretBytes = 32;            // random bytes in a secret (256 bits)
constexpr size_t kMaxPatternBytes = 256;       // longest map pattern accepted
constexpr const char* kSecretPrefix = "fmt_";  // tells a ForestMap token apart in configs / logs

std::string Hex(const unsigned char* data, size_t size) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string hex(2 * size, '0');
  for (size_t i = 0; i < size; ++i) {
    hex[2 * i] = kDigits[data[i] >> 4];
    hex[2 * i + 1] = kDigits[data[i] & 0xf];
  }
  return hex;
}

std::string RandomSecret() {
  std::array<unsigned char, kSecretBytes> bytes{};
  if (RAND_bytes(bytes.data(), static_cast<int>(bytes.size())) != 1) {
    throw StorageError(StorageError::Code::kInternal, "OpenSSL RAND_bytes failed");
  }
  return kSecretPrefix + Hex(bytes.data(), bytes.size());
}

#define FORESTMAP_TOKEN_COLUMNS "id, map_pattern, role, note, created_unix_ms, revoked_unix_ms"

TokenRecord ReadToken(const sqlite::Statement& row) {
  TokenRecord record;
  record.id = row.ColumnInt64(0);
  record.map_pattern = row.ColumnText(1);
  record.role = static_cast<Role>(row.ColumnInt64(2));
  record.note = row.ColumnText(3);
  record.created_unix_ms = row.ColumnInt64(4);
  record.revoked_unix_ms = row.ColumnIsNull(5) ? 0 : row.ColumnInt64(5);
  return record;
}

// Tokens in the server's SQLite file: one connection, one mutex.
class SqliteTokens final : public TokenBackend {
 public:
  SqliteTokens(const std::string& path, int busy_timeout_ms) {
    db_ = std::make_unique<sqlite::Database>(
        path, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX, busy_timeout_ms);
    sqlite::MigrateSchema(*db_, internal::SchemaSteps());
    if (path != ":memory:") db_->EnableWal();
  }

  int64_t Insert(const std::string& secret_sha256, const TokenRecord& record) override {
    std::lock_guard<std::mutex> lock(mutex_);
    sqlite::Statement insert(*db_,
                             "INSERT INTO access_tokens (secret_sha256, map_pattern, role, note, "
                             "created_unix_ms) VALUES (?1, ?2, ?3, ?4, ?5)");
    insert.BindText(1, secret_sha256);
    insert.BindText(2, record.map_pattern);
    insert.BindInt64(3, static_cast<int64_t>(record.role));
    insert.BindText(4, record.note);
    insert.BindInt64(5, record.created_unix_ms);
    insert.Run();
    return db_->LastInsertRowId();
  }

  std::vector<TokenRecord> List() override {
    std::lock_guard<std::mutex> lock(mutex_);
    sqlite::Statement query(*db_,
                            "SELECT " FORESTMAP_TOKEN_COLUMNS " FROM access_tokens ORDER BY id");
    std::vector<TokenRecord> records;
    while (query.Step()) records.push_back(ReadToken(query));
    return records;
  }

  bool Revoke(int64_t id, int64_t now_unix_ms) override {
    std::lock_guard<std::mutex> lock(mutex_);
    sqlite::Statement update(*db_,
                             "UPDATE access_tokens SET revoked_unix_ms = ?1 "
                             "WHERE id = ?2 AND revoked_unix_ms IS NULL");
    update.BindInt64(1, now_unix_ms);
    update.BindInt64(2, id);
    update.Run();
    return sqlite3_changes(db_->handle()) == 1;
  }

  std::optional<TokenRecord> FindValid(const std::string& secret_sha256) override {
    std::lock_guard<std::mutex> lock(mutex_);
    sqlite::Statement query(*db_, "SELECT " FORESTMAP_TOKEN_COLUMNS
                                  " FROM access_tokens WHERE secret_sha256 = ?1 AND "
                                  "revoked_unix_ms IS NULL");
    query.BindText(1, secret_sha256);
    if (!query.Step()) return std::nullopt;
    return ReadToken(query);
  }

  bool AnyToken() override {
    std::lock_guard<std::mutex> lock(mutex_);
    return db_->QueryInt64("SELECT EXISTS (SELECT 1 FROM access_tokens)") != 0;
  }

 private:
  std::mutex mutex_;
  std::unique_ptr<sqlite::Database> db_;
};

}  // namespace

const char* RoleName(Role role) {
  switch (role) {
    case Role::kRead:
      return "read";
    case Role::kWrite:
      return "write";
    case Role::kAdmin:
      return "admin";
  }
  return "unknown";
}

std::optional<Role> ParseRole(std::string_view name) {
  for (Role role : {Role::kRead, Role::kWrite, Role::kAdmin}) {
    if (name == RoleName(role)) return role;
  }
  return std::nullopt;
}

bool TokenRecord::Allows(Role needed, std::string_view map) const {
  if (revoked() || static_cast<int>(role) < static_cast<int>(needed)) return false;
  const std::string name(map);
  return fnmatch(map_pattern.c_str(), name.c_str(), 0) == 0;
}

std::string Sha256Hex(std::string_view data) {
  std::array<unsigned char, EVP_MAX_MD_SIZE> digest{};
  unsigned int size = 0;
  if (EVP_Digest(data.data(), data.size(), digest.data(), &size, EVP_sha256(), nullptr) != 1) {
    throw StorageError(StorageError::Code::kInternal, "OpenSSL SHA-256 failed");
  }
  return Hex(digest.data(), size);
}

TokenStore::TokenStore(const std::string& path, int busy_timeout_ms) {
  if (IsPostgresUri(path)) {
    backend_ = OpenPostgresTokens(path);
  } else {
    backend_ = std::make_unique<SqliteTokens>(path, busy_timeout_ms);
  }
}

TokenStore::~TokenStore() = default;

NewToken TokenStore::Create(const std::string& map_pattern, Role role, const std::string& note) {
  if (map_pattern.empty() || map_pattern.size() > kMaxPatternBytes) {
    throw StorageError(StorageError::Code::kInvalidArgument,
                       "token map pattern must be 1.." + std::to_string(kMaxPatternBytes) +
                           " bytes (a map name, a glob like 'plot-*', or '*')");
  }
  NewToken token;
  token.secret = RandomSecret();
  token.record.map_pattern = map_pattern;
  token.record.role = role;
  token.record.note = note;
  token.record.created_unix_ms = internal::NowUnixMs();
  token.record.id = backend_->Insert(Sha256Hex(token.secret), token.record);
  return token;
}

std::vector<TokenRecord> TokenStore::List() { return backend_->List(); }

bool TokenStore::Revoke(int64_t id) { return backend_->Revoke(id, internal::NowUnixMs()); }

std::optional<TokenRecord> TokenStore::Find(std::string_view secret) {
  return backend_->FindValid(Sha256Hex(secret));
}

bool TokenStore::AnyToken() {
  // Tokens are never deleted (revoked ones count): once true, always true, without a query.
  if (any_token_.load(std::memory_order_relaxed)) return true;
  const bool any = backend_->AnyToken();
  if (any) any_token_.store(true, std::memory_order_relaxed);
  return any;
}

}  // namespace forestmap::storage
