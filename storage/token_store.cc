#include "storage/token_store.h"

#include <fnmatch.h>
#include <openssl/evp.h>
#include <openssl/rand.h>

#include <array>
#include <cctype>

#include "storage/store_steps.h"
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

std::string_view BearerSecret(std::string_view authorization) {
  constexpr std::string_view kBearer = "bearer";
  if (authorization.size() <= kBearer.size() || authorization[kBearer.size()] != ' ') return {};
  for (size_t i = 0; i < kBearer.size(); ++i) {
    if (std::tolower(static_cast<unsigned char>(authorization[i])) != kBearer[i]) return {};
  }
  authorization.remove_prefix(kBearer.size());
  while (authorization.starts_with(' ')) authorization.remove_prefix(1);
  return authorization;
}

std::string Sha256Hex(std::string_view data) {
  std::array<unsigned char, EVP_MAX_MD_SIZE> digest{};
  unsigned int size = 0;
  if (EVP_Digest(data.data(), data.size(), digest.data(), &size, EVP_sha256(), nullptr) != 1) {
    throw StorageError(StorageError::Code::kInternal, "OpenSSL SHA-256 failed");
  }
  return Hex(digest.data(), size);
}

TokenStore::TokenStore(const std::string& path, int busy_timeout_ms)
    : backend_(OpenTokenBackend(path, busy_timeout_ms)) {}

TokenStore::~TokenStore() = default;

NewToken TokenStore::Create(const std::string& map_pattern, Role role, const std::string& note,
                            int64_t expires_unix_ms) {
  if (map_pattern.empty() || map_pattern.size() > kMaxPatternBytes) {
    throw StorageError(StorageError::Code::kInvalidArgument,
                       "token map pattern must be 1.." + std::to_string(kMaxPatternBytes) +
                           " bytes (a map name, a glob like 'plot-*', or '*')");
  }
  const int64_t now = internal::NowUnixMs();
  if (expires_unix_ms < 0 || (expires_unix_ms != 0 && expires_unix_ms <= now)) {
    throw StorageError(StorageError::Code::kInvalidArgument,
                       "a token's expiry must lie in the future");
  }
  NewToken token;
  token.secret = RandomSecret();
  token.record.map_pattern = map_pattern;
  token.record.role = role;
  token.record.note = note;
  token.record.created_unix_ms = now;
  token.record.expires_unix_ms = expires_unix_ms;
  token.record.id = backend_->Insert(Sha256Hex(token.secret), token.record);
  return token;
}

std::vector<TokenRecord> TokenStore::List() { return backend_->List(); }

bool TokenStore::Revoke(int64_t id) { return backend_->Revoke(id, internal::NowUnixMs()); }

std::optional<TokenRecord> TokenStore::Find(std::string_view secret) {
  std::optional<TokenRecord> token = backend_->FindValid(Sha256Hex(secret));
  if (token && token->expired(internal::NowUnixMs())) return std::nullopt;
  return token;
}

bool TokenStore::AnyToken() {
  // Tokens are never deleted (revoked ones count): once true, always true, without a query.
  if (any_token_.load(std::memory_order_relaxed)) return true;
  const bool any = backend_->AnyToken();
  if (any) any_token_.store(true, std::memory_order_relaxed);
  return any;
}

}  // namespace forestmap::storage
