#pragma once
// One store over two databases.
//
// VersionedMapStore (storage/versioned_map_store.h) implements every MapStore method once: the
// checks, the versioning rules (a change closes rows and inserts new ones, so every version
// stays readable), the counts and extents, the merge transaction, restore and prune, exactly-once
// writes and the pages of an export. StagedUpload (storage/staged_upload.h) does the same for
// uploads. Both speak to the database only through the two small interfaces of this header,
// which storage/sqlite/ and storage/postgres/ implement with their own SQL:
//   StoreBackend  where a call runs: a connection for a read or for a write, with the database's
//                 concurrency (SQLite: one writer under a mutex and a pool of WAL readers;
//                 PostgreSQL: a pool, writes serialized per map by an advisory lock);
//   StoreSession  one connection lent to one call: its transaction and the statements on rows.
// A StoreSession method is one statement (or one prepared statement run over a batch), never a
// call per row: the loops over rows (reading a million trees, inserting them with SQLite's
// spatial blocks or PostgreSQL's unnest arrays) stay inside the backend, in plain code over its
// own statements, so the virtual call costs nothing next to the statement it stands for.
// Why an interface and not a template over backend traits: the shared code is compiled once, a
// backend is a class a reader can follow, and the price is one indirect call per statement.
//
// SqliteMapStore and PostgresMapStore are thin shells that open their backend and hand it to
// VersionedMapStore; OpenMapStore (storage/open_store.h) picks one for a `--db` value.

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "storage/map_store.h"
#include "storage/staged_writes.h"
#include "storage/write_request.h"

namespace forestmap::storage {

// A map's row: its key in the database and what MapStore tells about it.
struct MapRow {
  int64_t id = 0;
  MapInfo info;
};

// A current tree row that a write closed: what the map's counts and extent need of it.
struct ClosedTree {
  int64_t id = 0;
  bool confirmed = false;
  double x = 0, y = 0;  // m
};

// Rows PruneVersions removed.
struct PrunedRows {
  int64_t trees = 0, observations = 0, versions = 0;
};

enum class TransactionKind {
  kRead,   // one snapshot of committed versions for the whole read
  kWrite,  // the writes of one call, applied whole or not at all
};

// One connection lent to one call (not thread-safe; the backend lends it to one thread). Tree
// methods take the MapRow to name the map in errors about stored values. "Current" rows belong
// to the map's current version (valid_to = kForever, storage/rows.h), "closed" rows to older
// versions only. Errors are thrown as StorageError.
class StoreSession {
 public:
  virtual ~StoreSession() = default;

  // ---- Transactions (through StoreTransaction) ----
  virtual void Begin(TransactionKind kind) = 0;
  virtual void Commit() = 0;
  virtual void Rollback() noexcept = 0;

  // ---- Maps ----
  virtual std::vector<MapInfo> ListMaps() = 0;  // by name
  virtual std::optional<MapRow> FindMap(const std::string& name) = 0;
  // Takes the lock that serializes the writes of map `map_id` to the end of the transaction.
  // False when the write transaction held it from its start (SQLite's BEGIN IMMEDIATE locks the
  // whole database); true when it was taken now, so rows read before may be stale.
  virtual bool LockMap(int64_t map_id) = 0;
  // The new map's id; kAlreadyExists when the name is taken.
  virtual int64_t InsertMap(const MapInfo& info) = 0;
  virtual void DeleteMap(const MapRow& map) = 0;  // with its trees, observations and history
  // Stores version, counts, extent and updated time of `map`.
  virtual void UpdateMap(const MapRow& map) = 0;
  // Extent of the current trees, by a scan (after removals that may shrink it).
  virtual std::optional<Extent> ScanExtent(int64_t map_id) = 0;

  // ---- History ----
  virtual void InsertVersion(int64_t map_id, const VersionRecord& record) = 0;
  virtual std::optional<VersionRecord> FindVersion(int64_t map_id, int64_t version) = 0;
  virtual std::optional<int64_t> OldestVersion(int64_t map_id) = 0;
  // Version numbers, newest first; limit > 0 keeps the first `limit`.
  virtual std::vector<int64_t> NewestVersions(int64_t map_id, int64_t limit) = 0;
  // Deletes the history before `first_kept` and the rows only it held (boundary and column-order
  // rows too, but the ones in force at `first_kept`).
  virtual PrunedRows PruneBefore(int64_t map_id, int64_t first_kept) = 0;

  // ---- Survey boundary (storage/boundary_json.h): one row per version that set it ----
  // The encoded boundary of `version`: the row of the newest version at or before it; "" when
  // there is none (or that row removed it).
  virtual std::string BoundaryAt(int64_t map_id, int64_t version) = 0;
  // The boundary from `version` on ("" removes it).
  virtual void InsertBoundary(int64_t map_id, int64_t version, const std::string& encoded) = 0;

  // ---- Order of the attribute columns (storage/attribute_json.h), kept as the boundary ----
  // The encoded order of `version` ("" when no version up to it stored one).
  virtual std::string ColumnsAt(int64_t map_id, int64_t version) = 0;
  // The order from `version` on.
  virtual void InsertColumns(int64_t map_id, int64_t version, const std::string& encoded) = 0;

  // ---- Removal log (MapChanges::removals) ----
  virtual void InsertRemovals(int64_t map_id, int64_t version,
                              const std::vector<TreeRemoval>& removals) = 0;
  // Those of the versions after `after_version`, by version and tree id.
  virtual std::vector<TreeRemoval> RemovalsAfter(int64_t map_id, int64_t after_version) = 0;

  // ---- Trees (results by id) ----
  virtual std::vector<TreeRecord> CurrentTrees(const MapRow& map) = 0;
  // The trees of an older `version`: current rows from then and closed rows valid then.
  virtual std::vector<TreeRecord> TreesAtVersion(const MapRow& map, int64_t version) = 0;
  // Current trees inside the box (inclusive), through the spatial index.
  virtual std::vector<TreeRecord> TreesInBox(const MapRow& map, const Extent& box) = 0;
  virtual std::vector<TreeRecord> TreesById(const MapRow& map, std::span<const int64_t> ids) = 0;
  // One page (storage/staged_writes.h) of the current rows valid at query.version, or of the
  // closed rows valid then: each in id order, at most query.limit.
  virtual std::vector<TreeRecord> CurrentPage(const MapRow& map, const TreePageQuery& query) = 0;
  virtual std::vector<TreeRecord> ClosedPage(const MapRow& map, const TreePageQuery& query) = 0;
  virtual std::optional<int64_t> MaxCurrentTreeId(int64_t map_id) = 0;
  virtual std::optional<int64_t> MaxTreeIdEver(int64_t map_id) = 0;  // of any version
  // Inserts trees[i] with id ids[i] as current rows valid from `valid_from`. kInvalidArgument
  // naming the tree (TreeLabel) for an id current in the map or attributes that are not UTF-8.
  virtual void InsertTrees(const MapRow& map, const std::vector<TreeRecord>& trees,
                           const std::vector<int64_t>& ids, int64_t valid_from) = 0;
  // Closes the current rows of these trees at `version`; returns those that had one.
  virtual std::vector<ClosedTree> CloseTrees(int64_t map_id, std::span<const int64_t> ids,
                                             int64_t version) = 0;
  // Closes every current tree and observation row at `version`; returns the observation rows.
  virtual int64_t CloseAllRows(int64_t map_id, int64_t version) = 0;
  // For restore: closed rows valid at `version`, and closing at `at` the current rows added
  // after `version` (returns their tree ids).
  virtual std::vector<TreeRecord> ClosedTreesAt(const MapRow& map, int64_t version) = 0;
  virtual std::vector<int64_t> CloseTreesAddedAfter(int64_t map_id, int64_t version,
                                                    int64_t at) = 0;

  // ---- Observations (results by id of the row) ----
  virtual std::vector<ObservationRecord> ObservationsOfTrees(int64_t map_id,
                                                             std::span<const int64_t> ids) = 0;
  virtual std::vector<ObservationRecord> ObservationsInCells(
      int64_t map_id, std::span<const ObservationCell> cells) = 0;
  virtual std::vector<ObservationRecord> FoldedObservationsOfTrees(
      int64_t map_id, std::span<const int64_t> ids) = 0;
  virtual std::vector<ObservationRecord> ObservationsOfSource(int64_t map_id,
                                                              const std::string& source) = 0;
  virtual std::vector<ObservationRecord> ObservationsOfSourceIn(int64_t map_id,
                                                                const std::string& source,
                                                                ObservationCell lo,
                                                                ObservationCell hi) = 0;
  virtual void InsertObservations(int64_t map_id, const std::vector<ObservationRecord>& rows,
                                  int64_t valid_from) = 0;
  // Closes these current rows at `version`; returns the ids of those that were current.
  virtual std::vector<int64_t> CloseObservations(int64_t map_id, std::span<const int64_t> ids,
                                                 int64_t version) = 0;
  // For restore, as for trees; closing returns the number of rows closed.
  virtual std::vector<ObservationRecord> ClosedObservationsAt(int64_t map_id, int64_t version) = 0;
  virtual int64_t CloseObservationsAddedAfter(int64_t map_id, int64_t version, int64_t at) = 0;

  // ---- Request log of exactly-once writes (storage/write_request.h) ----
  virtual void ExpireRequests(int64_t before_unix_ms) = 0;
  // False when `id` is stored already (nothing is written then).
  virtual bool InsertRequest(const std::string& id, const StoredRequest& answer) = 0;
  virtual std::optional<StoredRequest> FindRequest(const std::string& id) = 0;
};

// The transaction of a session, rolled back on destruction unless committed.
class StoreTransaction {
 public:
  StoreTransaction(StoreSession& session, TransactionKind kind) : session_(session) {
    session_.Begin(kind);
  }
  ~StoreTransaction() {
    if (!done_) session_.Rollback();
  }
  StoreTransaction(const StoreTransaction&) = delete;
  StoreTransaction& operator=(const StoreTransaction&) = delete;
  void Commit() {
    session_.Commit();
    done_ = true;
  }

 private:
  StoreSession& session_;
  bool done_ = false;
};

// Where the calls of a VersionedMapStore run. Thread-safe: every method may be called from many
// threads at once.
class StoreBackend {
 public:
  using Body = std::function<void(StoreSession&)>;
  virtual ~StoreBackend() = default;
  // Runs `body` on a connection for reading (the body opens its transaction, if any).
  virtual void WithReader(const Body& body) = 0;
  // Runs `body` on the connection for writing (SQLite: the one writer, under its mutex).
  virtual void WithWriter(const Body& body) = 0;
  // WithWriter for a write that frees room (delete, prune): it may use room the backend reserves
  // so that a full disk can be freed.
  virtual void WithFreeingWriter(const Body& body) { WithWriter(body); }
  // What the backend could not do when it opened (MapStore::OpenWarning); "" when nothing.
  virtual std::string OpenWarning() const { return {}; }
  // An upload staged in the database (storage/staged_upload.h).
  virtual std::unique_ptr<TreeUpload> BeginUpload(const std::string& name,
                                                  const UploadPlan& plan) = 0;
};

// ---- Steps on a session that reads and writes share (storage/store_backend.cc) ----

// The map's row; kNotFound for an unknown map.
MapRow RequireMap(StoreSession& session, const std::string& name);
// The map's row for a write, read under the map's write lock (StoreSession::LockMap).
MapRow LockMap(StoreSession& session, const std::string& name);
// The history entry of `version`, or kNotFound naming the versions that can be read.
VersionRecord RequireVersion(StoreSession& session, const MapRow& map, int64_t version);
// Commits a write transaction, honouring the thread's WriteRequest (storage/write_request.h):
// stores its answer under its id, refuses a passed deadline. `info`: the map after the write.
void CommitWrite(StoreSession& session, StoreTransaction& transaction, const MapInfo& info);
// Runs a write that frees room (delete, prune) with backend.WithFreeingWriter. When the disk is
// still full and the thread's WriteRequest has an id, runs it once more without storing its
// answer (the write needs no new room, the answer's row may: PostgreSQL reuses a deleted row's
// room only after VACUUM): a retry with that id is then applied again, not answered from the log.
void FreeRoom(StoreBackend& backend, const StoreBackend::Body& body);

}  // namespace forestmap::storage
