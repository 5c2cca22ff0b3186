// SQLite: uploads staged in the database (schema steps 6 and 7, storage/staged_upload.h).
//
// Append writes the trees of a chunk with their R*Tree blocks in its own short transaction.
// An upload that creates its map writes them as the final rows of the hidden map (step 7), so
// Commit only reveals the map row and writes its versions: a few rows whatever the upload's
// size. An upload to an existing map writes pending rows of `trees` (valid_to = -upload id,
// valid_from = the tree's index in the upload); Commit closes the old rows (replace), turns the
// pending rows current in one UPDATE and writes the version, in one last transaction. Between
// the transactions the writer connection is free, so writes to other maps (and reads, always) go
// on while an upload streams.

#include <algorithm>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "storage/sqlite/internal.h"
#include "storage/staged_upload.h"

namespace forestmap::storage::sqlite {
namespace {

using Code = StorageError::Code;

struct UploadRow {
  int64_t id = 0;
  int64_t map_id = 0;
  bool creates_map = false;
  std::optional<int64_t> first_rowid, last_rowid;  // rowids holding its pending rows
};

// Rowids an abort removes per transaction: other writers go on between the slices.
constexpr int64_t kAbortSliceRows = 20'000;

// Removes the staged rows of an upload with rowids first..last, and their blocks: its pending
// rows, or every row of the hidden map it creates (final rows since step 7, pending before).
void RemovePendingRows(Database& db, const UploadRow& upload, int64_t first, int64_t last) {
  Statement blocks(db,
                   "DELETE FROM tree_blocks WHERE id IN (SELECT b.id FROM tree_blocks AS b "
                   "WHERE b.min_map <= ?1 AND b.max_map >= ?1 AND b.map_id = ?1 AND "
                   "b.first_rowid BETWEEN ?2 AND ?3 AND (?5 OR EXISTS (SELECT 1 FROM trees AS t "
                   "WHERE t.rowid = b.first_rowid AND t.valid_to = ?4)))",
                   upload.map_id, first, last, -upload.id, upload.creates_map);
  blocks.Run();
  Statement(db,
            "DELETE FROM trees WHERE rowid BETWEEN ?1 AND ?2 AND (valid_to = ?3 OR (?4 AND "
            "map_id = ?5))",
            first, last, -upload.id, upload.creates_map, upload.map_id)
      .Run();
}

// Removes an upload's pending rows, their blocks, the map it was creating and its own row.
void RemoveUpload(Database& db, const UploadRow& upload) {
  if (upload.first_rowid) RemovePendingRows(db, upload, *upload.first_rowid, *upload.last_rowid);
  if (upload.creates_map) {
    Statement(db, "DELETE FROM maps WHERE id = ?1 AND creating_upload = ?2", upload.map_id,
              upload.id)
        .Run();
  }
  Statement(db, "DELETE FROM uploads WHERE id = ?1", upload.id).Run();
  ForgetChunks(db, upload.id);
}

std::optional<int64_t> MaxRowid(Database& db) {
  return Statement(db, "SELECT MAX(rowid) FROM trees").OptionalInt64();
}

// "trees[k]" of the upload.
std::string Label(int64_t index) { return "trees[" + std::to_string(index) + "]"; }

class Upload final : public StagedUpload {
 public:
  Upload(Backend& backend, std::string name, UploadPlan plan);
  ~Upload() override { Discard(); }
  Upload(const Upload&) = delete;
  Upload& operator=(const Upload&) = delete;

 private:
  void Begin(Database& db);
  MapRow RequireOwnMap(Database& db) const;
  [[noreturn]] void ThrowDuplicate(Database& db, const std::vector<TreeRecord>& trees,
                                   size_t index);

  void Stage(const std::vector<TreeRecord>& trees) override;  // one transaction
  void WithSession(const std::function<void(StoreSession&)>& body) override;
  MapRow Target(StoreSession& session) override;
  void MakeCurrent(StoreSession& session, const MapRow& map, int64_t version) override;
  void Forget(StoreSession& session) override;
  void Abort() noexcept override;
  void Finished() noexcept override;

  Backend& backend_;
  UploadRow row_;
};

Upload::Upload(Backend& backend, std::string name, UploadPlan plan)
    : StagedUpload(std::move(name), std::move(plan)), backend_(backend) {
  backend_.WithWriterDatabase([&](Database& db) { Begin(db); });
}

void Upload::Begin(Database& db) {
  Transaction transaction(db, Transaction::Kind::kWrite);
  if (plan().create_map) {
    // Hidden (creating_upload set) until Commit; its name is taken meanwhile.
    Statement insert(db,
                     "INSERT INTO maps (name, description, crs, version, tree_count, "
                     "created_unix_ms, updated_unix_ms, creating_upload) VALUES (?1, ?2, ?3, 1, 0, "
                     "?4, ?4, 0)",
                     name(), plan().description, plan().crs, internal::NowUnixMs());
    try {
      insert.Run();
    } catch (const StorageError& e) {
      if (e.code() != Code::kAlreadyExists) throw;
      throw StorageError(Code::kAlreadyExists, "map '" + name() +
                                                   "' already exists (or another upload is "
                                                   "creating it)");
    }
    row_.map_id = db.LastInsertRowId();
    row_.creates_map = true;
  } else {
    Session session(db);
    row_.map_id = RequireMap(session, name()).id;
  }
  Statement(db, "INSERT INTO uploads (map_id, creates_map, started_unix_ms) VALUES (?1, ?2, ?3)",
            row_.map_id, row_.creates_map, internal::NowUnixMs())
      .Run();
  row_.id = db.LastInsertRowId();
  if (row_.creates_map) {
    Statement(db, "UPDATE maps SET creating_upload = ?2 WHERE id = ?1", row_.map_id, row_.id).Run();
  }
  transaction.Commit();
}

// The map's row by id, hidden (an upload creating it) or not.
MapRow Upload::RequireOwnMap(Database& db) const {
  Statement select(db, "SELECT " FORESTMAP_MAP_COLUMNS " FROM maps WHERE id = ?1", row_.map_id);
  if (!select.Step()) {
    throw StorageError(Code::kNotFound,
                       "map '" + name() + "' was deleted during the upload; nothing was written");
  }
  return internal::ReadMapRow(Row(select));
}

void Upload::ThrowDuplicate(Database& db, const std::vector<TreeRecord>& trees, size_t index) {
  // The earlier row with the same id holds its index in valid_from (pending) or upload_chunks.
  const int64_t id = trees[index].id.value_or(-1);
  std::optional<int64_t> earlier_index;
  if (row_.creates_map) {
    earlier_index = StagedIndex(db, row_.id, row_.map_id, id);
  } else {
    Statement earlier(db,
                      "SELECT valid_from FROM trees WHERE valid_to = ?1 AND valid_to < 0 AND "
                      "tree_id = ?2",
                      -row_.id, id);
    if (earlier.Step()) earlier_index = earlier.ColumnInt64(0);
  }
  const std::string other = earlier_index ? Label(*earlier_index) : "an earlier tree";
  throw StorageError(Code::kInvalidArgument,
                     chunks().Label(chunks().staged() + static_cast<int64_t>(index)) + ".id " +
                         std::to_string(id) + " duplicates " + other +
                         ".id (an explicit id, or one the server gave a tree without id)");
}

void Upload::Stage(const std::vector<TreeRecord>& trees) {
  backend_.WithWriterDatabase([&](Database& db) {
    Transaction transaction(db, Transaction::Kind::kWrite);
    const MapRow map = RequireOwnMap(db);
    const bool append = plan().mode == WriteMode::kAppend && !row_.creates_map;
    const std::vector<int64_t> ids =
        chunks().Assign(trees, append ? Session(db).MaxCurrentTreeId(row_.map_id) : std::nullopt);
    const int64_t before = MaxRowid(db).value_or(0);
    try {
      if (row_.creates_map) {  // final rows of the hidden map
        const std::vector<size_t> order =
            InsertTrees(db, map, trees, ids, kCreatedTreesVersion, kForever, chunks().staged());
        RecordChunk(db, row_.id, before + 1, chunks().staged(), order);
      } else {
        InsertTrees(db, map, trees, ids, 0, -row_.id, chunks().staged());
      }
    } catch (const StagedDuplicate& duplicate) {
      ThrowDuplicate(db, trees, duplicate.index);
    }
    const int64_t last = MaxRowid(db).value_or(before);
    Statement(db,
              "UPDATE uploads SET first_rowid = COALESCE(first_rowid, ?2), last_rowid = ?3 WHERE "
              "id = ?1",
              row_.id, before + 1, last)
        .Run();
    transaction.Commit();
    if (!row_.first_rowid) row_.first_rowid = before + 1;
    row_.last_rowid = last;
  });
}

void Upload::WithSession(const std::function<void(StoreSession&)>& body) {
  backend_.WithWriter(body);
}

// The map's row (hidden until now when the upload creates it: then revealed as version 1).
MapRow Upload::Target(StoreSession& session) {
  Database& db = Session::DatabaseOf(session);
  MapRow map = RequireOwnMap(db);
  if (!row_.creates_map) return map;
  MapInfo& info = map.info;
  info.created_unix_ms = info.updated_unix_ms = internal::NowUnixMs();
  Statement(db, "UPDATE maps SET creating_upload = NULL, created_unix_ms = ?2 WHERE id = ?1",
            map.id, info.created_unix_ms)
      .Run();
  session.UpdateMap(map);
  session.InsertVersion(map.id, internal::CreationRecord(info));
  return map;
}

void Upload::MakeCurrent(StoreSession& session, const MapRow& map, int64_t version) {
  if (!row_.first_rowid || row_.creates_map) return;  // the created map's rows are final
  Database& db = Session::DatabaseOf(session);
  Statement flip(db,
                 "UPDATE trees SET valid_from = ?4, valid_to = " FORESTMAP_CURRENT
                 " WHERE rowid BETWEEN ?1 AND ?2 AND valid_to = ?3",
                 *row_.first_rowid, *row_.last_rowid, -row_.id, version);
  try {
    flip.Run();
    return;
  } catch (const StorageError& e) {
    if (e.code() != Code::kAlreadyExists) throw;  // UNIQUE trees_current: an id of the map
  }
  Statement clash(db,
                  "SELECT p.valid_from, p.tree_id FROM trees AS p WHERE p.rowid BETWEEN ?1 "
                  "AND ?2 AND p.valid_to = ?3 AND EXISTS (SELECT 1 FROM trees AS c INDEXED BY "
                  "trees_current WHERE c.map_id = ?4 AND c.tree_id = p.tree_id AND "
                  "c.valid_to = " FORESTMAP_CURRENT ") LIMIT 1",
                  *row_.first_rowid, *row_.last_rowid, -row_.id, map.id);
  std::string which = "a tree";
  if (clash.Step()) {
    which = "tree at index " + std::to_string(clash.ColumnInt64(0)) + " (id " +
            std::to_string(clash.ColumnInt64(1)) + ")";
  }
  throw StorageError(Code::kInvalidArgument,
                     "map '" + name() + "': " + which + ": tree id already exists in the map");
}

void Upload::Forget(StoreSession& session) {
  Statement(Session::DatabaseOf(session), "DELETE FROM uploads WHERE id = ?1", row_.id).Run();
}

void Upload::Finished() noexcept {
  try {  // after the commit, in its own transaction; left for the next open if it fails
    backend_.WithWriterDatabase([&](Database& db) {
      Transaction transaction(db, Transaction::Kind::kWrite);
      ForgetChunks(db, row_.id);
      transaction.Commit();
    });
  } catch (const StorageError&) {
  }
}

void Upload::Abort() noexcept {
  try {
    // The staged rows slice by slice (no read sees them), then the rest in one transaction.
    for (int64_t from = row_.first_rowid.value_or(1); row_.first_rowid && from <= *row_.last_rowid;
         from += kAbortSliceRows) {
      const int64_t to = std::min(*row_.last_rowid, from + kAbortSliceRows - 1);
      backend_.WithWriterDatabase([&](Database& db) {
        Transaction transaction(db, Transaction::Kind::kWrite);
        RemovePendingRows(db, row_, from, to);
        transaction.Commit();
      });
    }
    UploadRow rest = row_;
    rest.first_rowid.reset();  // its rows are gone
    backend_.WithWriterDatabase([&](Database& db) {
      Transaction transaction(db, Transaction::Kind::kWrite);
      RemoveUpload(db, rest);
      transaction.Commit();
    });
  } catch (...) {
    // Left for RemoveAbandonedUploads when a store next opens the database.
  }
}

}  // namespace

void RemoveAbandonedUploads(Database& db) {
  Transaction transaction(db, Transaction::Kind::kWrite);
  std::vector<UploadRow> uploads;
  {
    Statement select(db, "SELECT id, map_id, creates_map, first_rowid, last_rowid FROM uploads");
    while (select.Step()) {
      UploadRow row{select.ColumnInt64(0), select.ColumnInt64(1), select.ColumnInt64(2) != 0,
                    std::nullopt, std::nullopt};
      if (!select.ColumnIsNull(3)) row.first_rowid = select.ColumnInt64(3);
      if (!select.ColumnIsNull(4)) row.last_rowid = select.ColumnInt64(4);
      uploads.push_back(row);
    }
  }
  for (const UploadRow& upload : uploads) RemoveUpload(db, upload);
  ForgetChunks(db, -1);  // of uploads committed just before the process stopped
  transaction.Commit();
}

std::unique_ptr<TreeUpload> Backend::BeginUpload(const std::string& name, const UploadPlan& plan) {
  return std::make_unique<Upload>(*this, name, plan);
}

}  // namespace forestmap::storage::sqlite
