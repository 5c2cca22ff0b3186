// The PostgreSQL session (storage/store_backend.h): transactions, maps, history, prune and the
// request log. Tree and observation rows are in trees.cc.

#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "storage/postgres/internal.h"

namespace forestmap::storage::pg {
namespace {

// The answer bytes of a request as hex text (column response_hex).
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

std::string Int64Array(std::span<const int64_t> values) {
  ArrayLiteral array;
  for (const int64_t value : values) array.Int64(value);
  return array.Finish();
}

// ---- Transactions ----

// Reads run REPEATABLE READ READ ONLY (one snapshot), writes READ COMMITTED under the advisory
// lock of the map they write (LockMap).
void Session::Begin(TransactionKind kind) {
  transaction_.emplace(conn_, kind == TransactionKind::kWrite ? Transaction::Kind::kWrite
                                                              : Transaction::Kind::kRead);
}

void Session::Commit() {
  transaction_->Commit();
  transaction_.reset();
}

void Session::Rollback() noexcept { transaction_.reset(); }

// ---- Maps ----

std::vector<MapInfo> Session::ListMaps() {
  return ReadAll(conn_.Exec("SELECT " FORESTMAP_MAP_COLUMNS " FROM maps ORDER BY name"),
                 [](const Row& row) { return internal::ReadMapRow(row).info; });
}

std::optional<MapRow> Session::FindMap(const std::string& name) {
  const Result result =
      conn_.Exec("SELECT " FORESTMAP_MAP_COLUMNS " FROM maps WHERE name = $1", Params().Text(name));
  if (result.rows() == 0) return std::nullopt;
  return internal::ReadMapRow(Row(result, 0));
}

// The lock is held to the end of the transaction. READ COMMITTED: a statement after it sees every
// write committed before it was granted.
bool Session::LockMap(int64_t map_id) {
  conn_.Exec("SELECT pg_advisory_xact_lock($1)", Params().Int64(map_id));
  return true;
}

int64_t Session::InsertMap(const MapInfo& info) {
  return conn_
      .Exec(
          "INSERT INTO maps (name, description, crs, version, tree_count, created_unix_ms, "
          "updated_unix_ms) VALUES ($1, $2, $3, 1, 0, $4, $4) RETURNING id",
          Params()
              .Text(info.name)
              .Text(info.description)
              .Text(info.crs)
              .Int64(info.created_unix_ms))
      .Int64(0, 0);
}

// Trees, observations and history go with it (ON DELETE CASCADE).
void Session::DeleteMap(const MapRow& map) {
  conn_.Exec("DELETE FROM maps WHERE id = $1", Params().Int64(map.id));
}

void Session::UpdateMap(const MapRow& map) {
  Params params;
  params.Int64(map.id);
  internal::WriteMapValues(params, map.info);
  conn_.Exec(
      "UPDATE maps SET version = $2, tree_count = $3, min_x = $4, min_y = $5, max_x = $6, "
      "max_y = $7, updated_unix_ms = $8, confirmed_count = $9 WHERE id = $1",
      params);
}

std::optional<Extent> Session::ScanExtent(int64_t map_id) {
  const Result scan = conn_.Exec(
      "SELECT MIN(x), MIN(y), MAX(x), MAX(y) FROM trees WHERE map_id = $1 AND "
      "valid_to = " FORESTMAP_CURRENT,
      Params().Int64(map_id));
  if (scan.IsNull(0, 0)) return std::nullopt;
  return Extent{scan.Double(0, 0), scan.Double(0, 1), scan.Double(0, 2), scan.Double(0, 3)};
}

// ---- History ----

void Session::InsertVersion(int64_t map_id, const VersionRecord& record) {
  Params params;
  params.Int64(map_id);
  internal::WriteVersionValues(params, record);
  conn_.Exec("INSERT INTO map_versions (map_id, " FORESTMAP_VERSION_COLUMNS
             ") VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9, $10, $11, $12, $13)",
             params);
}

std::optional<VersionRecord> Session::FindVersion(int64_t map_id, int64_t version) {
  const Result select = conn_.Exec("SELECT " FORESTMAP_VERSION_COLUMNS
                                   " FROM map_versions WHERE map_id = $1 AND version = $2",
                                   Params().Int64(map_id).Int64(version));
  if (select.rows() == 0) return std::nullopt;
  return internal::ReadVersionRow(Row(select, 0));
}

std::optional<int64_t> Session::OldestVersion(int64_t map_id) {
  const Result first =
      conn_.Exec("SELECT MIN(version) FROM map_versions WHERE map_id = $1", Params().Int64(map_id));
  if (first.IsNull(0, 0)) return std::nullopt;
  return first.Int64(0, 0);
}

std::vector<int64_t> Session::NewestVersions(int64_t map_id, int64_t limit) {
  return ReadAll(
      conn_.Exec(
          "SELECT version FROM map_versions WHERE map_id = $1 ORDER BY version DESC LIMIT $2",
          Params().Int64(map_id).Int64(limit > 0 ? limit : std::numeric_limits<int64_t>::max())),
      [](const Row& row) { return row.Int64(0); });
}

PrunedRows Session::PruneBefore(int64_t map_id, int64_t first_kept) {
  const Params params = Params().Int64(map_id).Int64(first_kept);
  PrunedRows pruned;
  pruned.trees =
      conn_.Exec("DELETE FROM trees WHERE map_id = $1 AND valid_to <= $2", params).affected();
  pruned.observations =
      conn_.Exec("DELETE FROM observations WHERE map_id = $1 AND valid_to <= $2", params)
          .affected();
  pruned.versions =
      conn_.Exec("DELETE FROM map_versions WHERE map_id = $1 AND version < $2", params).affected();
  // Boundary and column-order rows before the ones in force at the first kept version.
  for (const char* sql :
       {"DELETE FROM map_boundaries WHERE map_id = $1 AND version < (SELECT MAX(version) FROM "
        "map_boundaries WHERE map_id = $1 AND version <= $2)",
        "DELETE FROM map_columns WHERE map_id = $1 AND version < (SELECT MAX(version) FROM "
        "map_columns WHERE map_id = $1 AND version <= $2)",
        "DELETE FROM tree_removals WHERE map_id = $1 AND version < $2"}) {
    conn_.Exec(sql, params);
  }
  return pruned;
}

// ---- Survey boundary ----

std::string Session::BoundaryAt(int64_t map_id, int64_t version) {
  const Result select = conn_.Exec(
      "SELECT polygons FROM map_boundaries WHERE map_id = $1 AND version <= $2 "
      "ORDER BY version DESC LIMIT 1",
      Params().Int64(map_id).Int64(version));
  return select.rows() == 0 ? std::string() : select.Text(0, 0);
}

void Session::InsertBoundary(int64_t map_id, int64_t version, const std::string& encoded) {
  conn_.Exec(
      "INSERT INTO map_boundaries (map_id, version, polygons) VALUES ($1, $2, $3) "
      "ON CONFLICT (map_id, version) DO UPDATE SET polygons = EXCLUDED.polygons",
      Params().Int64(map_id).Int64(version).Text(encoded));
}

// ---- Order of the attribute columns ----

std::string Session::ColumnsAt(int64_t map_id, int64_t version) {
  const Result select = conn_.Exec(
      "SELECT names FROM map_columns WHERE map_id = $1 AND version <= $2 "
      "ORDER BY version DESC LIMIT 1",
      Params().Int64(map_id).Int64(version));
  return select.rows() == 0 ? std::string() : select.Text(0, 0);
}

void Session::InsertColumns(int64_t map_id, int64_t version, const std::string& encoded) {
  conn_.Exec(
      "INSERT INTO map_columns (map_id, version, names) VALUES ($1, $2, $3) "
      "ON CONFLICT (map_id, version) DO UPDATE SET names = EXCLUDED.names",
      Params().Int64(map_id).Int64(version).Text(encoded));
}

// ---- Removal log ----

void Session::InsertRemovals(int64_t map_id, int64_t version,
                             const std::vector<TreeRemoval>& removals) {
  if (removals.empty()) return;
  ArrayLiteral ids, evidence;
  for (const TreeRemoval& removal : removals) {
    ids.Int64(removal.tree_id);
    evidence.Text(removal.evidence);
  }
  conn_.Exec(
      "INSERT INTO tree_removals (map_id, version, tree_id, evidence) SELECT $1, $2, u.* FROM "
      "unnest($3::bigint[], $4::text[]) AS u",
      Params().Int64(map_id).Int64(version).Text(ids.Finish()).Text(evidence.Finish()));
}

std::vector<TreeRemoval> Session::RemovalsAfter(int64_t map_id, int64_t after_version) {
  const Result select = conn_.Exec(
      "SELECT version, tree_id, evidence FROM tree_removals WHERE map_id = $1 AND version > $2 "
      "ORDER BY version, tree_id",
      Params().Int64(map_id).Int64(after_version));
  std::vector<TreeRemoval> removals;
  for (int r = 0; r < select.rows(); ++r) {
    removals.push_back({select.Int64(r, 1), select.Text(r, 2), select.Int64(r, 0)});
  }
  return removals;
}

// ---- Request log ----

void Session::ExpireRequests(int64_t before_unix_ms) {
  conn_.Exec("DELETE FROM request_log WHERE created_unix_ms < $1", Params().Int64(before_unix_ms));
}

bool Session::InsertRequest(const std::string& id, const StoredRequest& answer) {
  return conn_
             .Exec(
                 "INSERT INTO request_log (request_id, rpc, response_hex, created_unix_ms, "
                 "fingerprint) VALUES ($1, $2, $3, $4, $5) ON CONFLICT (request_id) DO NOTHING",
                 Params()
                     .Text(id)
                     .Text(answer.rpc)
                     .Text(ToHex(answer.response))
                     .Int64(answer.created_unix_ms)
                     .Text(answer.fingerprint))
             .affected() != 0;
}

std::optional<StoredRequest> Session::FindRequest(const std::string& id) {
  const Result result = conn_.Exec(
      "SELECT rpc, response_hex, created_unix_ms, fingerprint FROM request_log "
      "WHERE request_id = $1",
      Params().Text(id));
  if (result.rows() == 0) return std::nullopt;
  return StoredRequest{result.Text(0, 0), FromHex(result.Text(0, 1)), result.Int64(0, 2),
                       result.Text(0, 3)};
}

}  // namespace forestmap::storage::pg
