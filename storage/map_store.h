#pragma once
// Persistent storage of forest maps.

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "storage/write_request.h"

namespace forestmap::storage {

// The one error type of storage/. `code` tells the server which gRPC status to answer with.
class StorageError : public std::runtime_error {
 public:
  enum class Code {
    kNotFound,
    kAlreadyExists,
    kInvalidArgument,
    kConflict,
    kInternal,
    kDeadlineExceeded,  // a write whose WriteRequest deadline passed: nothing was committed
    // Faults of the database itself, each answered with a status that names it:
    kFull,         // no room: disk full or the size limit (SQLITE_FULL, SQLSTATE 53100)
    kReadOnly,     // the database cannot be written (read-only file, directory or file system)
    kCorrupt,      // the database is damaged (SQLITE_CORRUPT / NOTADB, SQLSTATE XX001 / XX002)
    kUnavailable,  // locked past the busy timeout, or the server unreachable: retry later
  };
  StorageError(Code code, const std::string& message) : std::runtime_error(message), code_(code) {}
  Code code() const { return code_; }

 private:
  Code code_;
};

struct Extent {
  double min_x = 0, min_y = 0, max_x = 0, max_y = 0;  // m, map frame
};

struct MapInfo {
  std::string name;
  std::string description;
  std::string crs;               // empty when unknown
  int64_t version = 0;           // 1 at creation, +1 on every change
  int64_t tree_count = 0;        // candidates and confirmed trees
  int64_t confirmed_count = 0;   // confirmed trees (surveyed or seen often enough)
  std::optional<Extent> extent;  // unset for an empty map
  int64_t created_unix_ms = 0;
  int64_t updated_unix_ms = 0;
  bool has_boundary = false;  // the version has a survey boundary (MapSnapshot::boundary)
};

enum class TreeStatus { kCandidate = 0, kConfirmed = 1 };

// One stored tree. Unknown z / dbh are std::nullopt (NULL in SQL). The defaults of the shared-map
// fields (status .. dbh_sigma) are those of a surveyed tree that no drone has observed yet.
struct TreeRecord {
  std::optional<int64_t> id;  // always set when read; on write, nullopt asks the store for one
  double x = 0, y = 0;        // m
  std::optional<double> z;    // m
  std::optional<double> dbh;  // m
  std::map<std::string, std::string> attributes;
  std::set<std::string> null_attributes;  // survey columns unknown (NA) for this tree
  TreeStatus status = TreeStatus::kConfirmed;
  int64_t observations = 0;              // observation rows behind the tree (incl. a survey prior)
  std::optional<double> position_sigma;  // m, 1-sigma horizontal uncertainty
  std::optional<double> dbh_sigma;       // m
  // Evidence of absence (server/app/absence_ledger.h): when a drone last saw the tree (unset: none
  // has since it was written), and the misses since then (JSON of the server's; unset: none).
  std::optional<int64_t> last_seen_unix_ms;
  std::optional<std::string> evidence;

  bool operator==(const TreeRecord&) const = default;
};

// One tree seen once (in one frame of one source, or a survey prior), in the MAP frame, with its
// provenance. The values are those the merge used (see algorithms::TreeObservation).
struct ObservationRecord {
  int64_t id = 0;  // assigned by the store; ignored on write
  int64_t tree_id = 0;
  std::string source;
  int64_t frame_id = 0;
  int32_t detection_index = 0;  // index in the frame's detections; -1 for a survey prior
  double x = 0, y = 0;          // m
  std::optional<double> z;      // m
  std::optional<double> dbh;    // m
  double weight_xy = 0;         // 1/m^2
  double weight_dbh = 0;        // 1/m^2
  double sensor_x = 0, sensor_y = 0, sensor_z = 0;  // m, map frame
  bool prior = false;                               // a survey prior
  int64_t version = 0;  // map version that added the row; set by the store
  // Folding (server/app/map_merger.h): a folded row is kept, with its source, but a merge reads
  // its tree's summary row instead; a summary row holds the statistics of the folded rows of its
  // tree (opaque text of the server's), with x, y, z, dbh and the weights their means and sums.
  bool folded = false;
  std::optional<std::string> summary;

  bool operator==(const ObservationRecord&) const = default;
};

// What made a map version.
enum class VersionKind {
  kCreate = 1,
  kUpload = 2,   // WriteTrees kAppend
  kReplace = 3,  // WriteTrees kReplace
  kObserve = 4,
  kRestore = 5,
  kRemoveSource = 6,
  kMigrated = 7,  // state found when the database was upgraded; older versions are gone
};

// One entry of a map's history, with counts of what changed.
struct VersionRecord {
  int64_t version = 0;
  int64_t created_unix_ms = 0;
  VersionKind kind = VersionKind::kCreate;
  std::string source;  // the source of an observe / remove-source version
  int64_t tree_count = 0;
  int64_t confirmed_count = 0;
  int64_t trees_added = 0, trees_updated = 0, trees_removed = 0;
  int64_t observations_added = 0, observations_removed = 0;
  int64_t restored_from = 0;  // kRestore only
};

// Current observation rows are indexed by square cells of the map frame: cell (i, j) holds the
// rows with floor(x / kObservationCellSize) == i and floor(y / kObservationCellSize) == j. The
// size is part of the stored data (schema version 3): changing it needs a migration.
inline constexpr double kObservationCellSize = 4.0;  // m
struct ObservationCell {
  int64_t x = 0, y = 0;  // cell indices
  auto operator<=>(const ObservationCell&) const = default;
};
ObservationCell CellOf(double x, double y);  // x, y in m

// A tree the evidence of absence removed (server/app/absence_ledger.h), as the removal log keeps
// it: the tree's id and the evidence (JSON of the server's), with the version that removed it.
struct TreeRemoval {
  int64_t tree_id = 0;
  std::string evidence;
  int64_t version = 0;  // set by the store
  bool operator==(const TreeRemoval&) const = default;
};

// Everything one merge changes, computed from what MergeReader showed.
struct MapChanges {
  // New trees (an id not current in the map) and new states of current trees (same id). Ids are
  // required: new trees take theirs from MergeReader::NextFreeTreeId() upwards.
  std::vector<TreeRecord> put_trees;
  std::vector<int64_t> removed_trees;                 // ids of current trees to drop
  std::vector<ObservationRecord> added_observations;  // tree_id must be a tree of the new version
  std::vector<int64_t> removed_observations;          // ids of current observation rows
  // Current rows (id set) to fold: each is closed and stored again with `folded` set, so that
  // every version keeps which rows its summaries stand for. Summary rows come and go through
  // added_observations and removed_summaries; neither they nor folding count as observations
  // added or removed in the history.
  std::vector<ObservationRecord> folded_observations;
  std::vector<int64_t> removed_summaries;  // ids of current summary rows
  // Trees of removed_trees that the evidence of absence removed, for the removal log.
  std::vector<TreeRemoval> removals;

  bool empty() const {
    return put_trees.empty() && removed_trees.empty() && added_observations.empty() &&
           removed_observations.empty() && folded_observations.empty() &&
           removed_summaries.empty() && removals.empty();
  }
};

// Read access inside a merge's write transaction: the map's current version, with no other
// writer in between until the merge commits. Reads do not see the merge's own changes.
class MergeReader {
 public:
  virtual ~MergeReader() = default;
  virtual const MapInfo& map() const = 0;
  // Current trees whose (x, y) lies inside the box (inclusive), by id.
  virtual std::vector<TreeRecord> TreesInBox(const Extent& box) = 0;
  // Current trees of these ids, by id (unknown ids are left out).
  virtual std::vector<TreeRecord> TreesById(std::span<const int64_t> ids) = 0;
  // Current observation rows of these trees that are not folded (summaries among them), by id.
  virtual std::vector<ObservationRecord> ObservationsOfTrees(std::span<const int64_t> ids) = 0;
  // Current folded observation rows of these trees, by id of the row.
  virtual std::vector<ObservationRecord> FoldedObservationsOfTrees(
      std::span<const int64_t> ids) = 0;
  // Current observation rows lying in these cells (see ObservationCell) that are not folded
  // (summaries among them), by id of the row.
  virtual std::vector<ObservationRecord> ObservationsInCells(
      std::span<const ObservationCell> cells) = 0;
  // Current observation rows of one source (folded or not), by id of the row.
  virtual std::vector<ObservationRecord> ObservationsOfSource(const std::string& source) = 0;
  // Current observation rows of one source that are not folded and lie in the cells from `lo` to
  // `hi` (inclusive, both axes), by id of the row.
  virtual std::vector<ObservationRecord> ObservationsOfSourceIn(const std::string& source,
                                                                ObservationCell lo,
                                                                ObservationCell hi) = 0;
  // Above every tree id the map ever had (in any version): ids for new trees start here.
  virtual int64_t NextFreeTreeId() = 0;
};

// How a merge is recorded, and the version it must build on.
struct MergeNote {
  VersionKind kind = VersionKind::kObserve;
  std::string source;
  // Set: the merge fails with kConflict (stale) unless this is still the current version.
  std::optional<int64_t> expected_version;
};

using MergeFunction = std::function<MapChanges(MergeReader&)>;

class TreeUpload;      // storage/staged_writes.h
struct UploadPlan;     // storage/staged_writes.h
struct TreePageQuery;  // storage/staged_writes.h

// A map's survey boundary: what its survey covered, polygons with holes in the map frame (m).
// A ring lists its vertices once (the first not repeated at the end), in either orientation.
// Stored with the trees and versioned with them; empty: the map has none.
struct BoundaryPoint {
  double x = 0, y = 0;  // m
  bool operator==(const BoundaryPoint&) const = default;
};
using BoundaryRing = std::vector<BoundaryPoint>;
struct BoundaryPolygon {
  BoundaryRing outer;
  std::vector<BoundaryRing> holes;
  bool operator==(const BoundaryPolygon&) const = default;
};
using Boundary = std::vector<BoundaryPolygon>;
// Vertices a boundary may have, all rings together.
inline constexpr size_t kMaxBoundaryVertices = 100000;

// A consistent snapshot of a map: its info, all its trees (sorted by id), its boundary and the
// order of its attribute columns, read together.
struct MapSnapshot {
  MapInfo info;
  std::vector<TreeRecord> trees;
  Boundary boundary;
  // The survey's attribute columns in the order of its files (UploadPlan::attribute_columns), for
  // exports to keep; names the trees do not have may be listed, and names of the trees that are
  // not listed (trees written without an order) follow the listed ones in name order on export.
  std::vector<std::string> attribute_columns;
};

enum class WriteMode {
  kAppend,   // add trees; an id already in the map is an error
  kReplace,  // the map's trees become exactly these
};

// What MapStore::PruneVersions dropped.
struct PruneResult {
  MapInfo info;                   // the map (unchanged: pruning makes no new version)
  int64_t versions_removed = 0;   // history entries dropped
  int64_t tree_rows_removed = 0;  // stored tree states no kept version holds
  int64_t observation_rows_removed = 0;
};

// Thread-safety: every method may be called from many threads at once. Each write is one
// transaction: it is applied whole or not at all. Errors are thrown as StorageError.
class MapStore {
 public:
  virtual ~MapStore() = default;

  // Throws kAlreadyExists if the name is taken, kInvalidArgument for an invalid name.
  virtual MapInfo CreateMap(const std::string& name, const std::string& description,
                            const std::string& crs) = 0;
  virtual std::vector<MapInfo> ListMaps() = 0;          // sorted by name
  virtual MapInfo GetMap(const std::string& name) = 0;  // kNotFound
  virtual void DeleteMap(const std::string& name) = 0;  // kNotFound

  // Writes trees in one transaction and bumps the version. Trees without an id get the next
  // free ids (above every id in the map and in `trees`), in order. Duplicate ids (within `trees`
  // or, in kAppend, against the map) -> kInvalidArgument naming the id; kNotFound for the map.
  virtual MapInfo WriteTrees(const std::string& name, const std::vector<TreeRecord>& trees,
                             WriteMode mode) = 0;

  // All trees of a map with the info of the same version.
  virtual MapSnapshot ReadMap(const std::string& name) = 0;

  // Trees whose (x, y) lies inside the box (inclusive), by id, through the spatial index.
  virtual std::vector<TreeRecord> TreesInBox(const std::string& name, const Extent& box) = 0;

  // ---- Versions (shared maps) ----

  // The trees of an older version (0 = current) with the info of that version (tree_count and
  // extent of that version; created_unix_ms of the map, updated_unix_ms of that version).
  // kNotFound for a version that never existed or predates the history (kMigrated).
  virtual MapSnapshot ReadMapVersion(const std::string& name, int64_t version) = 0;
  // The survey boundary of a version (0 = current; empty when it has none), kNotFound as above.
  // The default reads the whole version.
  virtual Boundary ReadBoundary(const std::string& name, int64_t version);
  // The order of the attribute columns of a version (MapSnapshot::attribute_columns), kNotFound
  // as above. The default reads the whole version.
  virtual std::vector<std::string> ReadAttributeColumns(const std::string& name, int64_t version);
  // The removal log (MapChanges::removals) of the versions after `after_version`, by version and
  // tree id. kNotFound for an unknown map.
  virtual std::vector<TreeRemoval> ListRemovals(const std::string& name, int64_t after_version) = 0;
  // The history, oldest first; `limit` > 0 keeps the newest `limit` entries.
  virtual std::vector<VersionRecord> ListVersions(const std::string& name, int64_t limit) = 0;
  // A new version whose trees and observations equal those of `version` (kNotFound as above).
  virtual MapInfo RestoreVersion(const std::string& name, int64_t version) = 0;
  // Runs `merge` inside ONE write transaction (reads and writes; concurrent merges of any map
  // serialize) and commits its changes as one new version described by `note`. Nothing is
  // written when `merge` throws (its exception propagates), when a write fails, or when the
  // changes are empty (then the current info is returned and no version is made).
  // kConflict when note.expected_version is set and is not the current version.
  virtual MapInfo Merge(const std::string& name, const MergeNote& note,
                        const MergeFunction& merge) = 0;

  // Keeps the newest `keep` (>= 1) versions of the map readable and drops the history before
  // them: their ReadMapVersion / RestoreVersion become kNotFound. One transaction; honours the
  // WriteRequest scope like every write. kInvalidArgument for keep < 1, kNotFound for the map.
  virtual PruneResult PruneVersions(const std::string& name, int64_t keep) = 0;

  // ---- Exactly-once writes (storage/write_request.h) ----

  // The answer stored for a request id by an earlier write, if any.
  virtual std::optional<StoredRequest> FindRequest(const std::string& request_id) = 0;

  // ---- Bounded memory (storage/staged_writes.h) ----

  // Starts an upload staged in the database. kNotFound for an unknown map (kAlreadyExists for an
  // existing one when plan.create_map). The default holds the trees in memory (MemoryUpload).
  virtual std::unique_ptr<TreeUpload> BeginUpload(const std::string& name, const UploadPlan& plan);
  // Trees of one readable version, by id, one page at a time: each page is its own short read,
  // and versions never change, so pages of one version fit together. kNotFound for an unknown
  // map or version; kConflict when the map was deleted (or created again: created_unix_ms
  // differs) or the version pruned since the first page. The default reads the whole version.
  virtual std::vector<TreeRecord> ReadTreesPage(const std::string& name,
                                                const TreePageQuery& query);
  // What the store could not do when it opened, for the server to log as a warning (a full disk
  // skipped a start-up write: reads are served, writes that need room fail as kFull); "" when
  // it opened whole.
  virtual std::string OpenWarning() const { return {}; }
};

// Valid map names: 1..128 characters of [A-Za-z0-9_.-]. Returns an error message or "".
std::string ValidateMapName(const std::string& name);

}  // namespace forestmap::storage
