// PostgresMapStore: exactly-once writes (request log, storage/write_request.h) and history
// retention (PruneVersions), as the SQLite store does them (sqlite_requests.cc, sqlite_prune.cc).

#include <chrono>
#include <cstdio>
#include <string>

#include "storage/checks.h"
#include "storage/postgres/internal.h"
#include "storage/store_steps.h"

namespace forestmap::storage {

using Code = StorageError::Code;
using pg::Connection;
using pg::Params;
using pg::Transaction;

namespace {

std::string ToHex(const std::string& bytes) {
  static const char* kDigits = "0123456789abcdef";
  std::string hex;
  hex.reserve(bytes.size() * 2);
  for (const unsigned char c : bytes) {
    hex += kDigits[c >> 4];
    hex += kDigits[c & 15];
  }
  return hex;
}

std::string FromHex(const std::string& hex) {
  auto value = [](char c) { return c <= '9' ? c - '0' : c - 'a' + 10; };
  std::string bytes(hex.size() / 2, '\0');
  for (size_t i = 0; i < bytes.size(); ++i) {
    bytes[i] = static_cast<char>(value(hex[2 * i]) * 16 + value(hex[2 * i + 1]));
  }
  return bytes;
}

}  // namespace

namespace pg_internal {

void CommitWrite(Connection& conn, Transaction& transaction, const MapInfo& info) {
  const WriteRequest* request = CurrentWriteRequest();
  if (request != nullptr) {
    if (!request->id.empty()) {
      const int64_t now = internal::NowUnixMs();
      conn.Exec("DELETE FROM request_log WHERE created_unix_ms < $1",
                Params().Int64(now - internal::kRequestLogRetentionMs));
      const pg::Result inserted = conn.Exec(
          "INSERT INTO request_log (request_id, rpc, response_hex, created_unix_ms) "
          "VALUES ($1, $2, $3, $4) ON CONFLICT (request_id) DO NOTHING",
          Params()
              .Text(request->id)
              .Text(request->rpc)
              .Text(ToHex(request->encode ? request->encode(info) : std::string()))
              .Int64(now));
      if (inserted.affected() == 0) ThrowAppliedConcurrently(*request);
    }
    CheckDeadlineBeforeCommit(*request);  // as close to COMMIT as possible
  }
  transaction.Commit();
}

}  // namespace pg_internal

std::optional<StoredRequest> PostgresMapStore::FindRequest(const std::string& request_id) {
  std::optional<StoredRequest> found;
  With([&](Connection& conn) {
    const pg::Result result = conn.Exec(
        "SELECT rpc, response_hex, created_unix_ms FROM request_log WHERE request_id = $1",
        Params().Text(request_id));
    if (result.rows() > 0) {
      found = StoredRequest{result.Text(0, 0), FromHex(result.Text(0, 1)), result.Int64(0, 2)};
    }
  });
  return found;
}

PruneResult PostgresMapStore::PruneVersions(const std::string& name, int64_t keep) {
  internal::CheckName(name);
  if (keep < 1) {
    throw StorageError(Code::kInvalidArgument,
                       "keep is " + std::to_string(keep) + "; at least the current version stays");
  }
  PruneResult result;
  With([&](Connection& conn) {
    Transaction transaction(conn, Transaction::Kind::kWrite);
    const pg_internal::MapRow map = pg_internal::LockMap(conn, name);
    result.info = map.info;
    const int64_t first_kept = map.info.version - keep + 1;
    if (first_kept <= 1) return;
    const Params params = Params().Int64(map.id).Int64(first_kept);
    result.tree_rows_removed =
        conn.Exec("DELETE FROM trees WHERE map_id = $1 AND valid_to <= $2", params).affected();
    result.observation_rows_removed =
        conn.Exec("DELETE FROM observations WHERE map_id = $1 AND valid_to <= $2", params)
            .affected();
    result.versions_removed =
        conn.Exec("DELETE FROM map_versions WHERE map_id = $1 AND version < $2", params).affected();
    pg_internal::CommitWrite(conn, transaction, map.info);
  });
  return result;
}

}  // namespace forestmap::storage
