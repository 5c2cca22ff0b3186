#pragma once
// Pieces of the SQLite backend shared by the files of storage/sqlite/: the backend and its
// session (storage/store_backend.h), the schema and connection settings, faults found at open,
// tree rows with their spatial blocks, and staged uploads. Not a public API.

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "storage/connection_pool.h"
#include "storage/rows.h"
#include "storage/sqlite/database.h"
#include "storage/sqlite/store.h"
#include "storage/store_backend.h"

namespace forestmap::storage::sqlite {

using internal::kForever;

// ---- Schema and connections (schema.cc, faults.cc) ----

// Schema steps for MigrateSchema, and the settings of every connection.
const std::vector<const char*>& SchemaSteps();
void ConfigureConnection(Database& db, const SqliteMapStoreOptions& options, bool read_only);
// Throws kInvalidArgument for a database without a ForestMap schema (PRAGMA user_version 0)
// that already holds tables: another program's file, which migrating would change.
void RefuseForeignDatabase(Database& db);
// Throws kReadOnly when `db` cannot be written: opened read-only by the OS, or a probe commit
// (rewriting PRAGMA user_version with its value) fails.
void RefuseReadOnlyDatabase(Database& db);
// Throws kReadOnly for database `path` with the cause the file system tells and `detail`.
[[noreturn]] void ThrowReadOnly(const std::string& path, const std::string& detail);
// PRAGMA max_page_count for a size limit of `max_mib` MiB (0: none) on this connection.
void LimitDatabaseSize(Database& db, int64_t max_mib);

// ---- Room for the writes that free room (reserve.cc) ----

// A file at `path` of `bytes` allocated blocks on the database's file system: when the disk is
// full, giving it back lets a delete, a prune or the start-up writes grow the WAL (every write,
// even one that frees pages, appends its pages to the WAL first). Not thread-safe (the writer's
// mutex guards it).
class ReservedRoom {
 public:
  ReservedRoom(std::string path, int64_t bytes);
  // Allocates the file's blocks (when it has fewer); false when the file system has no room for
  // all of them (the file keeps what it got) or `bytes` is 0.
  bool Hold();
  // Removes the file; true when it held room, which the file system has now.
  bool Release();

 private:
  std::string path_;
  int64_t bytes_;
};

// ---- Rows ----

// A row of a statement as storage/rows.h reads it.
class Row {
 public:
  explicit Row(const Statement& statement) : statement_(statement) {}
  bool IsNull(int c) const { return statement_.ColumnIsNull(c); }
  int64_t Int64(int c) const { return statement_.ColumnInt64(c); }
  double Double(int c) const { return statement_.ColumnDouble(c); }
  std::optional<double> OptionalDouble(int c) const { return statement_.ColumnOptionalDouble(c); }
  std::string Text(int c) const { return statement_.ColumnText(c); }
  bool Bool(int c) const { return statement_.ColumnInt64(c) != 0; }

 private:
  const Statement& statement_;
};

// Binds the values storage/rows.h writes to consecutive parameters from `first` on.
class Binder {
 public:
  Binder(Statement& statement, int first) : statement_(statement), next_(first) {}
  void Int64(int64_t v) { statement_.BindInt64(next_++, v); }
  void OptionalInt64(const std::optional<int64_t>& v) {
    v ? statement_.BindInt64(next_++, *v) : statement_.BindNull(next_++);
  }
  void Double(double v) { statement_.BindDouble(next_++, v); }
  void OptionalDouble(const std::optional<double>& v) { statement_.BindOptionalDouble(next_++, v); }
  void Text(std::string_view v) { statement_.BindText(next_++, v); }
  void OptionalText(const std::optional<std::string>& v) {
    v ? statement_.BindText(next_++, *v) : statement_.BindNull(next_++);
  }
  void Bool(bool v) { statement_.BindInt64(next_++, v ? 1 : 0); }

 private:
  Statement& statement_;
  int next_;
};

// Every row of `select` read by `read` (a storage/rows.h reader).
template <typename Read>
auto ReadAll(Statement& select, const Read& read) {
  std::vector<decltype(read(Row(select)))> rows;
  while (select.Step()) rows.push_back(read(Row(select)));
  return rows;
}

// Inserts trees[i] with id ids[i], valid from `valid_from` to `valid_to`, block by block with
// their R*Tree rows, in the returned order (consecutive rowids). A current id of the map ->
// kInvalidArgument naming the tree. Rows staged by an upload (upload.cc) pass
// pending_base >= 0: a duplicate id among them throws StagedDuplicate (see InsertTree).
struct StagedDuplicate {
  size_t index;  // in `trees`
};
std::vector<size_t> InsertTrees(Database& db, const MapRow& map,
                                const std::vector<TreeRecord>& trees,
                                const std::vector<int64_t>& ids, int64_t valid_from,
                                int64_t valid_to = kForever, int64_t pending_base = -1);

// ---- The backend ----

// One writer connection guarded by a mutex, and a pool of reader connections (none for
// ":memory:", whose database lives on the writer alone: reads take the mutex too).
class Backend final : public StoreBackend {
 public:
  Backend(const std::string& path, const SqliteMapStoreOptions& options);
  void WithReader(const Body& body) override;
  void WithWriter(const Body& body) override;
  // WithWriter, with WithRoom. After it, a checkpoint gives the WAL back to the file system for
  // later writes, and the room is reserved again when the file system has it.
  void WithFreeingWriter(const Body& body) override;
  std::string OpenWarning() const override { return open_warning_; }
  std::unique_ptr<TreeUpload> BeginUpload(const std::string& name, const UploadPlan& plan) override;
  // The writer connection, for the short transactions of an upload.
  void WithWriterDatabase(const std::function<void(Database&)>& body);

 private:
  // The writes of opening the database: the migration (refused when it has no room even with the
  // reserve), then the removal of abandoned uploads and the write probe, which a full disk skips
  // with a warning (open_warning_) so that the store still serves reads.
  void OpenWrites(const std::string& path);
  // Runs `step`; when it fails as kFull, runs it again after a checkpoint (which truncates the
  // WAL), and once more after giving back the reserved room.
  void WithRoom(const std::function<void()>& step);
  void AddOpenWarning(const std::string& warning);
  // A TRUNCATE checkpoint of the writer (waiting for readers up to the busy timeout); true when
  // it completed.
  bool Checkpoint();

  SqliteMapStoreOptions options_;
  ReservedRoom reserve_;
  std::string open_warning_;
  std::mutex writer_mutex_;
  std::unique_ptr<Database> writer_;
  std::unique_ptr<ConnectionPool<Database>> readers_;  // null for ":memory:"
};

// The StoreSession of a connection (session.cc, trees.cc).
class Session final : public StoreSession {
 public:
  explicit Session(Database& db) : db_(db) {}
  // The connection of `session`, a session of this backend (an upload's hooks get back the
  // session its WithSession made).
  static Database& DatabaseOf(StoreSession& session) { return static_cast<Session&>(session).db_; }

  void Begin(TransactionKind kind) override;
  void Commit() override;
  void Rollback() noexcept override;

  std::vector<MapInfo> ListMaps() override;
  std::optional<MapRow> FindMap(const std::string& name) override;
  bool LockMap(int64_t map_id) override;
  int64_t InsertMap(const MapInfo& info) override;
  void DeleteMap(const MapRow& map) override;
  void UpdateMap(const MapRow& map) override;
  std::optional<Extent> ScanExtent(int64_t map_id) override;

  void InsertVersion(int64_t map_id, const VersionRecord& record) override;
  std::optional<VersionRecord> FindVersion(int64_t map_id, int64_t version) override;
  std::optional<int64_t> OldestVersion(int64_t map_id) override;
  std::vector<int64_t> NewestVersions(int64_t map_id, int64_t limit) override;
  PrunedRows PruneBefore(int64_t map_id, int64_t first_kept) override;

  std::string BoundaryAt(int64_t map_id, int64_t version) override;
  void InsertBoundary(int64_t map_id, int64_t version, const std::string& encoded) override;
  std::string ColumnsAt(int64_t map_id, int64_t version) override;
  void InsertColumns(int64_t map_id, int64_t version, const std::string& encoded) override;
  void InsertRemovals(int64_t map_id, int64_t version,
                      const std::vector<TreeRemoval>& removals) override;
  std::vector<TreeRemoval> RemovalsAfter(int64_t map_id, int64_t after_version) override;

  std::vector<TreeRecord> CurrentTrees(const MapRow& map) override;
  std::vector<TreeRecord> TreesAtVersion(const MapRow& map, int64_t version) override;
  std::vector<TreeRecord> TreesInBox(const MapRow& map, const Extent& box) override;
  std::vector<TreeRecord> TreesById(const MapRow& map, std::span<const int64_t> ids) override;
  std::vector<TreeRecord> CurrentPage(const MapRow& map, const TreePageQuery& query) override;
  std::vector<TreeRecord> ClosedPage(const MapRow& map, const TreePageQuery& query) override;
  std::optional<int64_t> MaxCurrentTreeId(int64_t map_id) override;
  std::optional<int64_t> MaxTreeIdEver(int64_t map_id) override;
  void InsertTrees(const MapRow& map, const std::vector<TreeRecord>& trees,
                   const std::vector<int64_t>& ids, int64_t valid_from) override;
  std::vector<ClosedTree> CloseTrees(int64_t map_id, std::span<const int64_t> ids,
                                     int64_t version) override;
  int64_t CloseAllRows(int64_t map_id, int64_t version) override;
  std::vector<TreeRecord> ClosedTreesAt(const MapRow& map, int64_t version) override;
  std::vector<int64_t> CloseTreesAddedAfter(int64_t map_id, int64_t version, int64_t at) override;

  std::vector<ObservationRecord> ObservationsOfTrees(int64_t map_id,
                                                     std::span<const int64_t> ids) override;
  std::vector<ObservationRecord> ObservationsInCells(
      int64_t map_id, std::span<const ObservationCell> cells) override;
  std::vector<ObservationRecord> FoldedObservationsOfTrees(int64_t map_id,
                                                           std::span<const int64_t> ids) override;
  std::vector<ObservationRecord> ObservationsOfSource(int64_t map_id,
                                                      const std::string& source) override;
  std::vector<ObservationRecord> ObservationsOfSourceIn(int64_t map_id, const std::string& source,
                                                        ObservationCell lo,
                                                        ObservationCell hi) override;
  void InsertObservations(int64_t map_id, const std::vector<ObservationRecord>& rows,
                          int64_t valid_from) override;
  std::vector<int64_t> CloseObservations(int64_t map_id, std::span<const int64_t> ids,
                                         int64_t version) override;
  std::vector<ObservationRecord> ClosedObservationsAt(int64_t map_id, int64_t version) override;
  int64_t CloseObservationsAddedAfter(int64_t map_id, int64_t version, int64_t at) override;

  void ExpireRequests(int64_t before_unix_ms) override;
  bool InsertRequest(const std::string& id, const StoredRequest& answer) override;
  std::optional<StoredRequest> FindRequest(const std::string& id) override;

 private:
  Database& db_;
  std::optional<Transaction> transaction_;
};

// ---- Staged uploads (upload.cc, created_upload.cc) ----

// Removes the staged rows (and the map it was creating) of every upload left by a process that
// stopped; called when the store opens the database.
void RemoveAbandonedUploads(Database& db);
// Uploads that create their map (schema step 7): their trees are final rows of the hidden map,
// valid from kCreatedTreesVersion. Records where the rows of a chunk, from `first_rowid` on in
// `order` (InsertTrees), come from: the chunk starts at `first_index`.
inline constexpr int64_t kCreatedTreesVersion = 2;  // version 1: the map, created empty
void RecordChunk(Database& db, int64_t upload_id, int64_t first_rowid, int64_t first_index,
                 const std::vector<size_t>& order);
// The index in the upload of its staged row with tree id `tree_id` in map `map_id` (unset: none).
std::optional<int64_t> StagedIndex(Database& db, int64_t upload_id, int64_t map_id,
                                   int64_t tree_id);
// Removes the chunk records of `upload_id`, or with upload_id < 0 those of every upload that is
// no longer open.
void ForgetChunks(Database& db, int64_t upload_id);

}  // namespace forestmap::storage::sqlite
