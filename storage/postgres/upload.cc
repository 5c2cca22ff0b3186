// PostgresMapStore: uploads staged in the database and exports by pages (storage/staged_writes.h).
//
// An upload has its own session (connection): its trees go into a TEMP table of that session as
// they arrive, one autocommitted INSERT per chunk, so the server holds one chunk in memory and
// no lock meanwhile. Commit copies them into `trees` in one transaction under the map's advisory
// lock (writes to other maps go on in parallel), and creates the map in that same transaction
// when asked. A session that ends (an aborted upload, a killed server) takes its TEMP table
// with it, so nothing of an unfinished upload is ever left in the database.

#include <algorithm>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "storage/attribute_json.h"
#include "storage/checks.h"
#include "storage/postgres/connection.h"
#include "storage/postgres/internal.h"
#include "storage/postgres/store.h"
#include "storage/staged_writes.h"
#include "storage/store_steps.h"
#include "storage/upload_chunks.h"

namespace forestmap::storage {
namespace {

using Code = StorageError::Code;
using pg::Connection;
using pg::Params;
using pg_internal::MapRow;

constexpr const char* kCreateStaging =
    "CREATE TEMP TABLE upload_trees (seq BIGINT NOT NULL, tree_id BIGINT NOT NULL UNIQUE, "
    "x DOUBLE PRECISION NOT NULL, y DOUBLE PRECISION NOT NULL, z DOUBLE PRECISION, "
    "dbh DOUBLE PRECISION, attributes TEXT, status SMALLINT NOT NULL, observations BIGINT NOT "
    "NULL, position_sigma DOUBLE PRECISION, dbh_sigma DOUBLE PRECISION)";

class PostgresTreeUpload final : public TreeUpload {
 public:
  PostgresTreeUpload(const std::string& conninfo, std::string name, UploadPlan plan)
      : conn_(std::make_unique<Connection>(conninfo)),
        name_(std::move(name)),
        plan_(std::move(plan)),
        chunks_(name_, plan_.mode) {
    internal::CheckName(name_);
    std::optional<int64_t> id;
    try {
      id = pg_internal::RequireMap(*conn_, name_).id;
    } catch (const StorageError& e) {
      if (e.code() != Code::kNotFound || !plan_.create_map) throw;
    }
    if (id && plan_.create_map) {
      throw StorageError(Code::kAlreadyExists, "map '" + name_ + "' already exists");
    }
    map_id_ = id.value_or(0);
    conn_->ExecScript(kCreateStaging);
  }

  void Append(const std::vector<TreeRecord>& trees) override;
  MapInfo Commit() override;
  int64_t staged() const override { return chunks_.staged(); }

 private:
  void CheckEarlierIds(const std::vector<int64_t>& ids);
  void Insert(const std::vector<TreeRecord>& trees, const std::vector<int64_t>& ids);
  MapRow LockTarget(pg::Transaction& transaction);
  void CheckTakenIds(const MapRow& map);

  std::unique_ptr<Connection> conn_;  // null once committed or failed
  std::string name_;
  UploadPlan plan_;
  internal::UploadChunks chunks_;
  int64_t map_id_ = 0;  // the map appended to (0 when creating)
};

void PostgresTreeUpload::CheckEarlierIds(const std::vector<int64_t>& ids) {
  pg::ArrayLiteral array;
  for (const int64_t id : ids) array.Int64(id);
  const pg::Result clash = conn_->Exec(
      "SELECT u.k, t.seq, t.tree_id FROM unnest($1::bigint[]) WITH ORDINALITY AS u(id, k) JOIN "
      "upload_trees AS t ON t.tree_id = u.id ORDER BY u.k LIMIT 1",
      Params().Text(array.Finish()));
  if (clash.rows() == 0) return;
  throw StorageError(Code::kInvalidArgument,
                     chunks_.Label(chunks_.staged() + clash.Int64(0, 0) - 1) + ".id " +
                         std::to_string(clash.Int64(0, 2)) + " duplicates trees[" +
                         std::to_string(clash.Int64(0, 1)) +
                         "].id (an explicit id, or one the server gave a tree without id)");
}

void PostgresTreeUpload::Insert(const std::vector<TreeRecord>& trees,
                                const std::vector<int64_t>& ids) {
  for (size_t begin = 0; begin < trees.size(); begin += PostgresMapStore::kRowsPerInsert) {
    const size_t end = std::min(trees.size(), begin + PostgresMapStore::kRowsPerInsert);
    pg::ArrayLiteral seq;
    pg_internal::TreeColumnArrays columns;
    for (size_t i = begin; i < end; ++i) {
      const int64_t index = chunks_.staged() + static_cast<int64_t>(i);
      try {
        columns.Add(ids[i], trees[i]);
      } catch (const nlohmann::json::exception& e) {
        throw StorageError(Code::kInvalidArgument,
                           chunks_.Label(index) + ": attributes are not valid UTF-8: " + e.what());
      }
      seq.Int64(index);
    }
    Params params;
    params.Text(seq.Finish());
    columns.AppendTo(params);
    conn_->Exec(
        "INSERT INTO upload_trees SELECT * FROM unnest($1::bigint[], $2::bigint[], "
        "$3::float8[], $4::float8[], $5::float8[], $6::float8[], $7::text[], $8::smallint[], "
        "$9::bigint[], $10::float8[], $11::float8[])",
        params);
  }
}

void PostgresTreeUpload::Append(const std::vector<TreeRecord>& trees) {
  if (!conn_) throw StorageError(Code::kInternal, "upload to '" + name_ + "' already finished");
  if (trees.empty()) return;
  try {
    chunks_.Check(trees);
    std::optional<int64_t> map_max;
    if (plan_.mode == WriteMode::kAppend && map_id_ != 0) {
      const pg::Result max = conn_->Exec(
          "SELECT MAX(tree_id) FROM trees WHERE map_id = $1 AND valid_to = " FORESTMAP_PG_CURRENT,
          Params().Int64(map_id_));
      if (!max.IsNull(0, 0)) map_max = max.Int64(0, 0);
    }
    const std::vector<int64_t> ids = chunks_.Assign(trees, map_max);
    CheckEarlierIds(ids);
    Insert(trees, ids);
    chunks_.Staged(trees);
  } catch (...) {
    conn_.reset();  // the session goes, and its staged rows with it
    throw;
  }
}

MapRow PostgresTreeUpload::LockTarget(pg::Transaction& /*transaction*/) {
  if (!plan_.create_map) {
    const MapRow map = pg_internal::LockMap(*conn_, name_);
    if (map.id != map_id_) {
      throw StorageError(Code::kNotFound,
                         "map '" + name_ + "' was deleted during the upload; nothing was written");
    }
    return map;
  }
  MapRow map;
  map.info = internal::NewMapInfo(name_, plan_.description, plan_.crs);
  const MapInfo& info = map.info;
  try {
    map.id = conn_
                 ->Exec(
                     "INSERT INTO maps (name, description, crs, version, tree_count, "
                     "created_unix_ms, updated_unix_ms) VALUES ($1, $2, $3, 1, 0, $4, $4) "
                     "RETURNING id",
                     Params()
                         .Text(name_)
                         .Text(info.description)
                         .Text(info.crs)
                         .Int64(info.created_unix_ms))
                 .Int64(0, 0);
  } catch (const StorageError& e) {
    if (e.code() != Code::kAlreadyExists) throw;
    throw StorageError(Code::kAlreadyExists, "map '" + name_ + "' already exists");
  }
  conn_->Exec("SELECT pg_advisory_xact_lock($1)", Params().Int64(map.id));
  pg_internal::InsertVersion(*conn_, map.id, internal::CreationRecord(info));
  return map;
}

void PostgresTreeUpload::CheckTakenIds(const MapRow& map) {
  const pg::Result taken = conn_->Exec(
      "SELECT u.seq, u.tree_id FROM upload_trees AS u WHERE EXISTS (SELECT 1 FROM trees AS t "
      "WHERE t.map_id = $1 AND t.tree_id = u.tree_id AND t.valid_to = " FORESTMAP_PG_CURRENT
      ") ORDER BY u.seq LIMIT 1",
      Params().Int64(map.id));
  if (taken.rows() == 0) return;
  throw StorageError(Code::kInvalidArgument, "map '" + name_ + "': tree at index " +
                                                 std::to_string(taken.Int64(0, 0)) + " (id " +
                                                 std::to_string(taken.Int64(0, 1)) +
                                                 "): tree id already exists in the map");
}

MapInfo PostgresTreeUpload::Commit() {
  if (!conn_) throw StorageError(Code::kInternal, "upload to '" + name_ + "' already finished");
  MapInfo result;
  try {
    pg::Transaction transaction(*conn_, pg::Transaction::Kind::kWrite);
    MapRow map = LockTarget(transaction);
    MapInfo& info = map.info;
    const bool replace = plan_.mode == WriteMode::kReplace;
    const int64_t staged = chunks_.staged();
    const bool changes = staged > 0 || (replace && info.tree_count > 0);
    if (changes) {
      const int64_t version = info.version + 1;
      const Params close = Params().Int64(map.id).Int64(version);
      int64_t closed = 0;
      if (replace) {
        conn_->Exec(
            "UPDATE trees SET valid_to = $2 WHERE map_id = $1 AND valid_to = " FORESTMAP_PG_CURRENT,
            close);
        closed = conn_
                     ->Exec(
                         "UPDATE observations SET valid_to = $2 WHERE map_id = $1 AND "
                         "valid_to = " FORESTMAP_PG_CURRENT,
                         close)
                     .affected();
      } else {
        CheckTakenIds(map);
      }
      conn_->Exec(
          "INSERT INTO trees (map_id, valid_from, valid_to, tree_id, x, y, z, dbh, "
          "attributes, status, observations, position_sigma, dbh_sigma) SELECT $1, "
          "$2, " FORESTMAP_PG_CURRENT
          ", tree_id, x, y, z, dbh, attributes, status, "
          "observations, position_sigma, dbh_sigma FROM upload_trees ORDER BY seq",
          close);
      const VersionRecord record = chunks_.Apply(info, closed);
      pg_internal::UpdateMapRow(*conn_, map);
      pg_internal::InsertVersion(*conn_, map.id, record);
    }
    if (changes || plan_.create_map) {
      pg_internal::CommitWrite(*conn_, transaction, info);
    } else {
      transaction.Commit();
    }
    result = info;
  } catch (...) {
    conn_.reset();
    throw;
  }
  conn_.reset();  // the session ends, and the TEMP table with it
  return result;
}

// Binds $1 map id, $2 version, $3 after id, $4 limit, $5..$8 the box (infinite without one).
Params PageParams(int64_t map_id, const TreePageQuery& query) {
  const Extent box = internal::PageBox(query);
  Params params;
  params.Int64(map_id).Int64(query.version);
  params.Int64(internal::PageAfterId(query)).Int64(query.limit);
  params.Double(box.min_x).Double(box.max_x).Double(box.min_y).Double(box.max_y);
  return params;
}

}  // namespace

std::unique_ptr<TreeUpload> PostgresMapStore::BeginUpload(const std::string& name,
                                                          const UploadPlan& plan) {
  return std::make_unique<PostgresTreeUpload>(conninfo_, name, plan);
}

std::vector<TreeRecord> PostgresMapStore::ReadTreesPage(const std::string& name,
                                                        const TreePageQuery& query) {
  internal::CheckName(name);
  internal::CheckPageQuery(name, query);
  std::vector<TreeRecord> trees;
  With([&](Connection& conn) {
    pg::Transaction transaction(conn, pg::Transaction::Kind::kRead);
    const MapRow map = pg_internal::RequireMap(conn, name);
    internal::CheckPageTarget(name, query, map.info);
    if (query.version != map.info.version) pg_internal::RequireVersion(conn, map, query.version);
    const Params params = PageParams(map.id, query);
    trees = pg_internal::ReadTreeRows(
        conn.Exec("SELECT " FORESTMAP_PG_TREE_COLUMNS
                  " FROM trees AS t WHERE t.map_id = $1 AND t.valid_to = " FORESTMAP_PG_CURRENT
                  " AND t.valid_from <= $2 AND t.tree_id > $3 AND t.x >= $5 AND t.x <= $6 AND "
                  "t.y >= $7 AND t.y <= $8 ORDER BY t.tree_id LIMIT $4",
                  params),
        name);
    if (query.version != map.info.version) {
      std::vector<TreeRecord> closed = pg_internal::ReadTreeRows(
          conn.Exec("SELECT " FORESTMAP_PG_TREE_COLUMNS
                    " FROM trees AS t WHERE t.map_id = $1 AND t.valid_to <> " FORESTMAP_PG_CURRENT
                    " AND t.valid_from <= $2 AND t.valid_to > $2 AND t.tree_id > $3 AND "
                    "t.x >= $5 AND t.x <= $6 AND t.y >= $7 AND t.y <= $8 ORDER BY t.tree_id "
                    "LIMIT $4",
                    params),
          name);
      trees.insert(trees.end(), closed.begin(), closed.end());
      internal::SortAndTrimPage(trees, query.limit);
    }
    transaction.Commit();
  });
  return trees;
}

}  // namespace forestmap::storage
