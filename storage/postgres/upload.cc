// PostgreSQL: uploads staged in the database (storage/staged_upload.h).
//
// An upload has its own session (connection): its trees go into a TEMP table of that session as
// they arrive, one autocommitted INSERT per chunk, so the server holds one chunk in memory and
// no lock meanwhile. Commit copies them into `trees` in one transaction under the map's advisory
// lock (writes to other maps go on in parallel), and creates the map in that same transaction
// when asked. A session that ends (an aborted upload, a killed server) takes its TEMP table
// with it, so nothing of an unfinished upload is ever left in the database.

#include <algorithm>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "storage/attribute_json.h"
#include "storage/postgres/internal.h"
#include "storage/staged_upload.h"

namespace forestmap::storage::pg {
namespace {

using Code = StorageError::Code;

constexpr const char* kCreateStaging =
    "CREATE TEMP TABLE upload_trees (seq BIGINT NOT NULL, tree_id BIGINT NOT NULL UNIQUE, "
    "x DOUBLE PRECISION NOT NULL, y DOUBLE PRECISION NOT NULL, z DOUBLE PRECISION, "
    "dbh DOUBLE PRECISION, attributes TEXT, status SMALLINT NOT NULL, observations BIGINT NOT "
    "NULL, position_sigma DOUBLE PRECISION, dbh_sigma DOUBLE PRECISION, last_seen_unix_ms "
    "BIGINT, evidence TEXT)";

class Upload final : public StagedUpload {
 public:
  Upload(const std::string& conninfo, std::string name, UploadPlan plan);

 private:
  void CheckEarlierIds(const std::vector<int64_t>& ids);
  void Insert(const std::vector<TreeRecord>& trees, const std::vector<int64_t>& ids);
  void CheckTakenIds(const MapRow& map);

  void Stage(const std::vector<TreeRecord>& trees) override;
  void WithSession(const std::function<void(StoreSession&)>& body) override;
  MapRow Target(StoreSession& session) override;
  void MakeCurrent(StoreSession& session, const MapRow& map, int64_t version) override;
  void Abort() noexcept override { conn_.reset(); }  // its TEMP table goes with the session
  void Finished() noexcept override { conn_.reset(); }

  std::unique_ptr<Connection> conn_;  // null once committed or failed
  int64_t map_id_ = 0;                // the map appended to (0 when creating)
};

Upload::Upload(const std::string& conninfo, std::string name, UploadPlan plan)
    : StagedUpload(std::move(name), std::move(plan)),
      conn_(std::make_unique<Connection>(conninfo)) {
  Session session(*conn_);
  const std::optional<MapRow> map = session.FindMap(this->name());
  if (!map && !this->plan().create_map) RequireMap(session, this->name());  // kNotFound
  if (map && this->plan().create_map) {
    throw StorageError(Code::kAlreadyExists, "map '" + this->name() + "' already exists");
  }
  map_id_ = map ? map->id : 0;
  conn_->ExecScript(kCreateStaging);
}

void Upload::CheckEarlierIds(const std::vector<int64_t>& ids) {
  const Result clash = conn_->Exec(
      "SELECT u.k, t.seq, t.tree_id FROM unnest($1::bigint[]) WITH ORDINALITY AS u(id, k) JOIN "
      "upload_trees AS t ON t.tree_id = u.id ORDER BY u.k LIMIT 1",
      Params().Text(Int64Array(ids)));
  if (clash.rows() == 0) return;
  throw StorageError(Code::kInvalidArgument,
                     chunks().Label(chunks().staged() + clash.Int64(0, 0) - 1) + ".id " +
                         std::to_string(clash.Int64(0, 2)) + " duplicates trees[" +
                         std::to_string(clash.Int64(0, 1)) +
                         "].id (an explicit id, or one the server gave a tree without id)");
}

void Upload::Insert(const std::vector<TreeRecord>& trees, const std::vector<int64_t>& ids) {
  const size_t step = PostgresMapStore::kRowsPerInsert;
  for (size_t begin = 0; begin < trees.size(); begin += step) {
    const size_t end = std::min(trees.size(), begin + step);
    ColumnArrays columns(13);
    for (size_t i = begin; i < end; ++i) {
      const int64_t index = chunks().staged() + static_cast<int64_t>(i);
      std::optional<std::string> attributes;
      try {
        attributes = internal::EncodeAttributes(trees[i].attributes, trees[i].null_attributes);
      } catch (const nlohmann::json::exception& e) {
        throw StorageError(Code::kInvalidArgument,
                           chunks().Label(index) + ": attributes are not valid UTF-8: " + e.what());
      }
      columns.Int64(index);  // seq
      internal::WriteTreeValues(columns, ids[i], trees[i], attributes);
      columns.EndRow();
    }
    Params params;
    columns.AppendTo(params);
    conn_->Exec(
        "INSERT INTO upload_trees SELECT * FROM unnest($1::bigint[], $2::bigint[], "
        "$3::float8[], $4::float8[], $5::float8[], $6::float8[], $7::text[], $8::smallint[], "
        "$9::bigint[], $10::float8[], $11::float8[], $12::bigint[], $13::text[])",
        params);
  }
}

void Upload::Stage(const std::vector<TreeRecord>& trees) {
  const bool append = plan().mode == WriteMode::kAppend && map_id_ != 0;
  const std::vector<int64_t> ids =
      chunks().Assign(trees, append ? MaxCurrentTreeId(*conn_, map_id_) : std::nullopt);
  CheckEarlierIds(ids);
  Insert(trees, ids);
}

void Upload::WithSession(const std::function<void(StoreSession&)>& body) {
  Session session(*conn_);
  body(session);
}

MapRow Upload::Target(StoreSession& session) {
  if (!plan().create_map) {
    const MapRow map = LockMap(session, name());
    if (map.id != map_id_) {
      throw StorageError(Code::kNotFound,
                         "map '" + name() + "' was deleted during the upload; nothing was written");
    }
    return map;
  }
  MapRow map;
  map.info = internal::NewMapInfo(name(), plan().description, plan().crs);
  try {
    map.id = session.InsertMap(map.info);
  } catch (const StorageError& e) {
    if (e.code() != Code::kAlreadyExists) throw;
    throw StorageError(Code::kAlreadyExists, "map '" + name() + "' already exists");
  }
  session.LockMap(map.id);
  session.InsertVersion(map.id, internal::CreationRecord(map.info));
  return map;
}

void Upload::CheckTakenIds(const MapRow& map) {
  const Result taken = conn_->Exec(
      "SELECT u.seq, u.tree_id FROM upload_trees AS u WHERE EXISTS (SELECT 1 FROM trees AS t "
      "WHERE t.map_id = $1 AND t.tree_id = u.tree_id AND t.valid_to = " FORESTMAP_CURRENT
      ") ORDER BY u.seq LIMIT 1",
      Params().Int64(map.id));
  if (taken.rows() == 0) return;
  throw StorageError(Code::kInvalidArgument, "map '" + name() + "': tree at index " +
                                                 std::to_string(taken.Int64(0, 0)) + " (id " +
                                                 std::to_string(taken.Int64(0, 1)) +
                                                 "): tree id already exists in the map");
}

// Runs on the upload's own connection, which `session` wraps.
void Upload::MakeCurrent(StoreSession& /*session*/, const MapRow& map, int64_t version) {
  if (plan().mode == WriteMode::kAppend) CheckTakenIds(map);
  conn_->Exec(
      "INSERT INTO trees (map_id, valid_from, valid_to, tree_id, x, y, z, dbh, attributes, "
      "status, observations, position_sigma, dbh_sigma, last_seen_unix_ms, evidence) SELECT $1, "
      "$2, " FORESTMAP_CURRENT
      ", tree_id, x, y, z, dbh, attributes, status, observations, position_sigma, dbh_sigma, "
      "last_seen_unix_ms, evidence FROM upload_trees ORDER BY seq",
      Params().Int64(map.id).Int64(version));
}

}  // namespace

std::unique_ptr<TreeUpload> Backend::BeginUpload(const std::string& name, const UploadPlan& plan) {
  return std::make_unique<Upload>(conninfo_, name, plan);
}

}  // namespace forestmap::storage::pg
