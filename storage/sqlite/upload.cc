// SqliteMapStore: uploads staged in the database (schema steps 6 and 7, storage/staged_writes.h).
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
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "storage/sqlite/database.h"
#include "storage/sqlite/internal.h"
#include "storage/sqlite/store.h"
#include "storage/staged_writes.h"
#include "storage/upload_chunks.h"

namespace forestmap::storage {
namespace {

using sqlite::Database;
using sqlite::Statement;
using sqlite::Transaction;
using Code = StorageError::Code;
using internal::MapRow;

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
                   "WHERE t.rowid = b.first_rowid AND t.valid_to = ?4)))");
  blocks.BindInt64(1, upload.map_id);
  blocks.BindInt64(2, first);
  blocks.BindInt64(3, last);
  blocks.BindInt64(4, -upload.id);
  blocks.BindInt64(5, upload.creates_map ? 1 : 0);
  blocks.Run();
  Statement rows(db,
                 "DELETE FROM trees WHERE rowid BETWEEN ?1 AND ?2 AND (valid_to = ?3 OR "
                 "(?4 AND map_id = ?5))");
  rows.BindInt64(1, first);
  rows.BindInt64(2, last);
  rows.BindInt64(3, -upload.id);
  rows.BindInt64(4, upload.creates_map ? 1 : 0);
  rows.BindInt64(5, upload.map_id);
  rows.Run();
}

// Removes an upload's pending rows, their blocks, the map it was creating and its own row.
void RemoveUpload(Database& db, const UploadRow& upload) {
  if (upload.first_rowid) RemovePendingRows(db, upload, *upload.first_rowid, *upload.last_rowid);
  if (upload.creates_map) {
    Statement map(db, "DELETE FROM maps WHERE id = ?1 AND creating_upload = ?2");
    map.BindInt64(1, upload.map_id);
    map.BindInt64(2, upload.id);
    map.Run();
  }
  Statement row(db, "DELETE FROM uploads WHERE id = ?1");
  row.BindInt64(1, upload.id);
  row.Run();
  internal::ForgetChunks(db, upload.id);
}

std::optional<int64_t> MaxRowid(Database& db) {
  Statement select(db, "SELECT MAX(rowid) FROM trees");
  if (!select.Step() || select.ColumnIsNull(0)) return std::nullopt;
  return select.ColumnInt64(0);
}

std::optional<int64_t> MaxCurrentId(Database& db, int64_t map_id) {
  Statement select(db,
                   "SELECT MAX(tree_id) FROM trees INDEXED BY trees_current WHERE "
                   "map_id = ?1 AND valid_to = " FORESTMAP_CURRENT);
  select.BindInt64(1, map_id);
  if (!select.Step() || select.ColumnIsNull(0)) return std::nullopt;
  return select.ColumnInt64(0);
}

// "trees[k]" of the upload.
std::string Label(int64_t index) { return "trees[" + std::to_string(index) + "]"; }

}  // namespace

void internal::RemoveAbandonedUploads(Database& db) {
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
  internal::ForgetChunks(db, -1);  // of uploads committed just before the process stopped
  transaction.Commit();
}

class SqliteTreeUpload final : public TreeUpload {
 public:
  SqliteTreeUpload(SqliteMapStore& store, std::string name, UploadPlan plan);
  ~SqliteTreeUpload() override { Abort(); }
  SqliteTreeUpload(const SqliteTreeUpload&) = delete;
  SqliteTreeUpload& operator=(const SqliteTreeUpload&) = delete;

  void Append(const std::vector<TreeRecord>& trees) override;
  MapInfo Commit() override;
  int64_t staged() const override { return chunks_.staged(); }

 private:
  void Begin(Database& db);
  MapRow RequireOwnMap(Database& db) const;
  [[noreturn]] void ThrowDuplicate(Database& db, const std::vector<TreeRecord>& trees,
                                   size_t index) const;
  void Stage(const std::vector<TreeRecord>& trees);  // one transaction
  void Reveal(Database& db, MapRow& map);  // the map it creates becomes visible, version 1
  void Flip(Database& db, const MapRow& map, int64_t version);
  void Abort() noexcept;

  SqliteMapStore& store_;
  std::string name_;
  UploadPlan plan_;
  UploadRow row_;
  internal::UploadChunks chunks_;
  bool done_ = false;  // committed or aborted
};

SqliteTreeUpload::SqliteTreeUpload(SqliteMapStore& store, std::string name, UploadPlan plan)
    : store_(store), name_(std::move(name)), plan_(std::move(plan)), chunks_(name_, plan_.mode) {
  internal::CheckName(name_);
  store_.WithWriter([&](Database& db) { Begin(db); });
}

void SqliteTreeUpload::Begin(Database& db) {
  Transaction transaction(db, Transaction::Kind::kWrite);
  if (plan_.create_map) {
    // Hidden (creating_upload set) until Commit; its name is taken meanwhile.
    Statement insert(db,
                     "INSERT INTO maps (name, description, crs, version, tree_count, "
                     "created_unix_ms, updated_unix_ms, creating_upload) VALUES (?1, ?2, ?3, 1, 0, "
                     "?4, ?4, 0)");
    insert.BindText(1, name_);
    insert.BindText(2, plan_.description);
    insert.BindText(3, plan_.crs);
    insert.BindInt64(4, internal::NowUnixMs());
    try {
      insert.Run();
    } catch (const StorageError& e) {
      if (e.code() != Code::kAlreadyExists) throw;
      throw StorageError(Code::kAlreadyExists, "map '" + name_ +
                                                   "' already exists (or another upload is "
                                                   "creating it)");
    }
    row_.map_id = db.LastInsertRowId();
    row_.creates_map = true;
  } else {
    const MapRow map = internal::RequireMap(db, name_);
    row_.map_id = map.id;
  }
  Statement insert(
      db, "INSERT INTO uploads (map_id, creates_map, started_unix_ms) VALUES (?1, ?2, ?3)");
  insert.BindInt64(1, row_.map_id);
  insert.BindInt64(2, row_.creates_map ? 1 : 0);
  insert.BindInt64(3, internal::NowUnixMs());
  insert.Run();
  row_.id = db.LastInsertRowId();
  if (row_.creates_map) {
    Statement mark(db, "UPDATE maps SET creating_upload = ?2 WHERE id = ?1");
    mark.BindInt64(1, row_.map_id);
    mark.BindInt64(2, row_.id);
    mark.Run();
  }
  transaction.Commit();
}

MapRow SqliteTreeUpload::RequireOwnMap(Database& db) const {
  Statement select(db, "SELECT " FORESTMAP_MAP_COLUMNS " FROM maps WHERE id = ?1");
  select.BindInt64(1, row_.map_id);
  if (!select.Step()) {
    throw StorageError(Code::kNotFound,
                       "map '" + name_ + "' was deleted during the upload; nothing was written");
  }
  return internal::ReadMapRow(select);
}

void SqliteTreeUpload::ThrowDuplicate(Database& db, const std::vector<TreeRecord>& trees,
                                      size_t index) const {
  // The earlier row with the same id holds its index in valid_from (pending) or upload_chunks.
  const int64_t id = trees[index].id.value_or(-1);
  std::optional<int64_t> earlier_index;
  if (row_.creates_map) {
    earlier_index = internal::StagedIndex(db, row_.id, row_.map_id, id);
  } else {
    Statement earlier(db,
                      "SELECT valid_from FROM trees WHERE valid_to = ?1 AND valid_to < 0 AND "
                      "tree_id = ?2");
    earlier.BindInt64(1, -row_.id);
    earlier.BindInt64(2, id);
    if (earlier.Step()) earlier_index = earlier.ColumnInt64(0);
  }
  const std::string other = earlier_index ? Label(*earlier_index) : "an earlier tree";
  throw StorageError(Code::kInvalidArgument,
                     chunks_.Label(chunks_.staged() + static_cast<int64_t>(index)) + ".id " +
                         std::to_string(id) + " duplicates " + other +
                         ".id (an explicit id, or one the server gave a tree without id)");
}

void SqliteTreeUpload::Append(const std::vector<TreeRecord>& trees) {
  if (done_) throw StorageError(Code::kInternal, "upload to '" + name_ + "' already finished");
  if (trees.empty()) return;
  try {
    chunks_.Check(trees);
    Stage(trees);
  } catch (...) {
    Abort();  // a failed upload is over: its staged rows go now
    throw;
  }
  chunks_.Staged(trees);
}

void SqliteTreeUpload::Stage(const std::vector<TreeRecord>& trees) {
  store_.WithWriter([&](Database& db) {
    Transaction transaction(db, Transaction::Kind::kWrite);
    const MapRow map = RequireOwnMap(db);
    const bool append = plan_.mode == WriteMode::kAppend && !row_.creates_map;
    const std::vector<int64_t> ids =
        chunks_.Assign(trees, append ? MaxCurrentId(db, row_.map_id) : std::nullopt);
    const int64_t before = MaxRowid(db).value_or(0);
    try {
      if (row_.creates_map) {  // final rows of the hidden map
        const std::vector<size_t> order =
            internal::InsertTrees(db, map, trees, ids, internal::kCreatedTreesVersion,
                                  internal::kForever, chunks_.staged());
        internal::RecordChunk(db, row_.id, before + 1, chunks_.staged(), order);
      } else {
        internal::InsertTrees(db, map, trees, ids, 0, -row_.id, chunks_.staged());
      }
    } catch (const internal::StagedDuplicate& duplicate) {
      ThrowDuplicate(db, trees, duplicate.index);
    }
    const int64_t last = MaxRowid(db).value_or(before);
    Statement update(db,
                     "UPDATE uploads SET first_rowid = COALESCE(first_rowid, ?2), last_rowid = ?3 "
                     "WHERE id = ?1");
    update.BindInt64(1, row_.id);
    update.BindInt64(2, before + 1);
    update.BindInt64(3, last);
    update.Run();
    transaction.Commit();
    if (!row_.first_rowid) row_.first_rowid = before + 1;
    row_.last_rowid = last;
  });
}

void SqliteTreeUpload::Flip(Database& db, const MapRow& map, int64_t version) {
  if (!row_.first_rowid || row_.creates_map) return;  // the created map's rows are final
  Statement flip(db, "UPDATE trees SET valid_from = ?4, valid_to = " FORESTMAP_CURRENT
                     " WHERE rowid BETWEEN ?1 AND ?2 AND valid_to = ?3");
  flip.BindInt64(1, *row_.first_rowid);
  flip.BindInt64(2, *row_.last_rowid);
  flip.BindInt64(3, -row_.id);
  flip.BindInt64(4, version);
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
                  "c.valid_to = " FORESTMAP_CURRENT ") LIMIT 1");
  clash.BindInt64(1, *row_.first_rowid);
  clash.BindInt64(2, *row_.last_rowid);
  clash.BindInt64(3, -row_.id);
  clash.BindInt64(4, map.id);
  std::string which = "a tree";
  if (clash.Step()) {
    which = "tree at index " + std::to_string(clash.ColumnInt64(0)) + " (id " +
            std::to_string(clash.ColumnInt64(1)) + ")";
  }
  throw StorageError(Code::kInvalidArgument,
                     "map '" + name_ + "': " + which + ": tree id already exists in the map");
}

void SqliteTreeUpload::Reveal(Database& db, MapRow& map) {
  MapInfo& info = map.info;
  info.created_unix_ms = info.updated_unix_ms = internal::NowUnixMs();
  Statement reveal(db,
                   "UPDATE maps SET creating_upload = NULL, created_unix_ms = ?2 WHERE id = ?1");
  reveal.BindInt64(1, map.id);
  reveal.BindInt64(2, info.created_unix_ms);
  reveal.Run();
  internal::UpdateMapRow(db, map);
  VersionRecord created;
  created.version = 1;
  created.created_unix_ms = info.created_unix_ms;
  created.kind = VersionKind::kCreate;
  internal::InsertVersion(db, map.id, created);
}

MapInfo SqliteTreeUpload::Commit() {
  if (done_) throw StorageError(Code::kInternal, "upload to '" + name_ + "' already finished");
  MapInfo result;
  try {
    store_.WithWriter([&](Database& db) {
      Transaction transaction(db, Transaction::Kind::kWrite);
      MapRow map = RequireOwnMap(db);
      const bool replace = plan_.mode == WriteMode::kReplace;
      const bool changes = chunks_.staged() > 0 || (replace && map.info.tree_count > 0);
      if (row_.creates_map) Reveal(db, map);
      if (changes) {
        const int64_t version = map.info.version + 1;
        // A created map has no old rows: its current rows are the upload's.
        const int64_t closed =
            replace && !row_.creates_map ? internal::CloseAllCurrentRows(db, map.id, version) : 0;
        Flip(db, map, version);
        const VersionRecord record = chunks_.Apply(map.info, closed);
        internal::UpdateMapRow(db, map);
        internal::InsertVersion(db, map.id, record);
      }
      Statement remove(db, "DELETE FROM uploads WHERE id = ?1");
      remove.BindInt64(1, row_.id);
      remove.Run();
      if (changes || row_.creates_map) {
        internal::CommitWrite(db, transaction, map.info);
      } else {
        transaction.Commit();  // nothing changed: no version, no answer stored
      }
      result = map.info;
    });
  } catch (...) {
    Abort();
    throw;
  }
  done_ = true;
  try {  // after the commit, in its own transaction; left for the next open if it fails
    store_.WithWriter([&](Database& db) {
      Transaction transaction(db, Transaction::Kind::kWrite);
      internal::ForgetChunks(db, row_.id);
      transaction.Commit();
    });
  } catch (const StorageError&) {
  }
  return result;
}

void SqliteTreeUpload::Abort() noexcept {
  if (done_) return;
  done_ = true;
  try {
    // The staged rows slice by slice (no read sees them), then the rest in one transaction.
    for (int64_t from = row_.first_rowid.value_or(1); row_.first_rowid && from <= *row_.last_rowid;
         from += kAbortSliceRows) {
      const int64_t to = std::min(*row_.last_rowid, from + kAbortSliceRows - 1);
      store_.WithWriter([&](Database& db) {
        Transaction transaction(db, Transaction::Kind::kWrite);
        RemovePendingRows(db, row_, from, to);
        transaction.Commit();
      });
    }
    UploadRow rest = row_;
    rest.first_rowid.reset();  // its rows are gone
    store_.WithWriter([&](Database& db) {
      Transaction transaction(db, Transaction::Kind::kWrite);
      RemoveUpload(db, rest);
      transaction.Commit();
    });
  } catch (...) {
    // Left for RemoveAbandonedUploads when a store next opens the database.
  }
}

std::unique_ptr<TreeUpload> SqliteMapStore::BeginUpload(const std::string& name,
                                                        const UploadPlan& plan) {
  return std::make_unique<SqliteTreeUpload>(*this, name, plan);
}

}  // namespace forestmap::storage
