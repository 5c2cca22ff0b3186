// VersionedMapStore::Merge: the merge's reads and its changes in one write transaction.

#include <algorithm>
#include <limits>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "storage/checks.h"
#include "storage/store_steps.h"
#include "storage/versioned_map_store.h"

namespace forestmap::storage {

using Code = StorageError::Code;

namespace {

// The trees a merge puts, counted into `info` (each as a new row: the caller subtracts the rows
// it closes): their ids in order and their extent.
struct PutTrees {
  std::vector<int64_t> ids;
  std::optional<Extent> extent;
};

// kConflict (stale) when `note` expects another version than `map`'s current one.
void CheckExpectedVersion(const MergeNote& note, const MapInfo& map) {
  if (note.expected_version && *note.expected_version != map.version) {
    throw StorageError(Code::kConflict,
                       "map '" + map.name + "' is at version " + std::to_string(map.version) +
                           ", not at the base version " + std::to_string(*note.expected_version) +
                           " (rejected as stale; fetch the map and retry, or merge anyway)");
  }
}

PutTrees CountPutTrees(MapInfo& info, const std::vector<TreeRecord>& put_trees) {
  PutTrees put;
  put.ids.reserve(put_trees.size());
  for (const TreeRecord& tree : put_trees) {
    put.ids.push_back(*tree.id);
    info.tree_count += 1;
    info.confirmed_count += tree.status == TreeStatus::kConfirmed ? 1 : 0;
    put.extent = internal::Union(put.extent, Extent{tree.x, tree.y, tree.x, tree.y});
  }
  return put;
}

// kInvalidArgument for a merge's tree or observation to remove that is not current in the map.
StorageError TreeToRemoveMissing(const std::string& map_name, int64_t id) {
  return StorageError(
      Code::kInvalidArgument,
      "map '" + map_name + "': merge: tree " + std::to_string(id) + " to remove is not in the map");
}

StorageError ObservationToRemoveMissing(const std::string& map_name, int64_t id) {
  return StorageError(Code::kInvalidArgument, "map '" + map_name + "': merge: observation " +
                                                  std::to_string(id) +
                                                  " to remove is not current in the map");
}

// Whether (x, y) lies on the border of `extent` (a closed row there may shrink it).
bool OnBorder(const std::optional<Extent>& extent, double x, double y) {
  return extent &&
         (x == extent->min_x || x == extent->max_x || y == extent->min_y || y == extent->max_y);
}

// Read access of a merge: the writer's session inside its write transaction.
class SessionMergeReader final : public MergeReader {
 public:
  SessionMergeReader(StoreSession& session, const MapRow& map) : session_(session), map_(map) {}

  const MapInfo& map() const override { return map_.info; }

  std::vector<TreeRecord> TreesInBox(const Extent& box) override {
    internal::CheckBox(map_.info.name, box);
    return session_.TreesInBox(map_, box);
  }
  std::vector<TreeRecord> TreesById(std::span<const int64_t> ids) override {
    return session_.TreesById(map_, ids);
  }
  std::vector<ObservationRecord> ObservationsOfTrees(std::span<const int64_t> ids) override {
    return session_.ObservationsOfTrees(map_.id, ids);
  }
  std::vector<ObservationRecord> FoldedObservationsOfTrees(std::span<const int64_t> ids) override {
    return session_.FoldedObservationsOfTrees(map_.id, ids);
  }
  std::vector<ObservationRecord> ObservationsInCells(
      std::span<const ObservationCell> cells) override {
    return session_.ObservationsInCells(map_.id, cells);
  }
  std::vector<ObservationRecord> ObservationsOfSource(const std::string& source) override {
    return session_.ObservationsOfSource(map_.id, source);
  }
  std::vector<ObservationRecord> ObservationsOfSourceIn(const std::string& source,
                                                        ObservationCell lo,
                                                        ObservationCell hi) override {
    return session_.ObservationsOfSourceIn(map_.id, source, lo, hi);
  }

  int64_t NextFreeTreeId() override {
    const std::optional<int64_t> max_id = session_.MaxTreeIdEver(map_.id);
    if (!max_id) return 1;
    if (*max_id == std::numeric_limits<int64_t>::max()) {
      throw StorageError(Code::kInvalidArgument,
                         "map '" + map_.info.name + "': no free tree ids left for new trees");
    }
    return std::max<int64_t>(*max_id + 1, 1);
  }

 private:
  StoreSession& session_;
  const MapRow& map_;
};

// Closes the current rows of trees `ids` at `version`, taking the rows that left out of the map's
// counts; returns the ids that had a current row. Sets `boundary` when a closed tree lay on the
// extent's border (the extent must then be rescanned).
std::vector<int64_t> CloseTrees(StoreSession& session, MapRow& map, std::span<const int64_t> ids,
                                int64_t version, bool& boundary) {
  std::vector<int64_t> closed_ids;
  MapInfo& info = map.info;
  for (const ClosedTree& closed : session.CloseTrees(map.id, ids, version)) {
    closed_ids.push_back(closed.id);
    info.tree_count -= 1;
    info.confirmed_count -= closed.confirmed ? 1 : 0;
    if (OnBorder(info.extent, closed.x, closed.y)) boundary = true;
  }
  return closed_ids;
}

// The first of `wanted` (in order) that `closed` does not hold, each closed id counting once: a
// row to remove that was not current, or that the changes name twice.
std::optional<int64_t> FirstNotClosed(const std::vector<int64_t>& wanted,
                                      const std::vector<int64_t>& closed) {
  std::multiset<int64_t> left(closed.begin(), closed.end());
  for (const int64_t id : wanted) {
    const auto it = left.find(id);
    if (it == left.end()) return id;
    left.erase(it);
  }
  return std::nullopt;
}

// Closes the current observation rows `ids` at `version`; kInvalidArgument when one is not
// current (or named twice).
std::vector<int64_t> CloseObservations(StoreSession& session, const MapRow& map,
                                       std::span<const int64_t> ids, int64_t version) {
  if (ids.empty()) return {};
  std::vector<int64_t> closed = session.CloseObservations(map.id, ids, version);
  if (const std::optional<int64_t> id =
          FirstNotClosed(std::vector<int64_t>(ids.begin(), ids.end()), closed)) {
    throw ObservationToRemoveMissing(map.info.name, *id);
  }
  return closed;
}

// Writes `changes` as version map.version + 1 and updates `map` (row and info).
void ApplyChanges(StoreSession& session, MapRow& map, const MergeNote& note,
                  const MapChanges& changes) {
  internal::CheckPutTrees(map.info.name, changes);
  VersionRecord record = internal::NextVersion(map.info, note.kind, note.source);
  bool boundary = false;
  const std::vector<int64_t> removed =
      CloseTrees(session, map, changes.removed_trees, record.version, boundary);
  if (const std::optional<int64_t> id = FirstNotClosed(changes.removed_trees, removed)) {
    throw TreeToRemoveMissing(map.info.name, *id);
  }
  record.trees_removed = static_cast<int64_t>(removed.size());
  const PutTrees put = CountPutTrees(map.info, changes.put_trees);
  record.trees_updated =
      static_cast<int64_t>(CloseTrees(session, map, put.ids, record.version, boundary).size());
  record.trees_added = static_cast<int64_t>(put.ids.size()) - record.trees_updated;
  session.InsertTrees(map, changes.put_trees, put.ids, record.version);

  const std::vector<int64_t> closed =
      CloseObservations(session, map, changes.removed_observations, record.version);
  CloseObservations(session, map, changes.removed_summaries, record.version);
  std::vector<int64_t> folded_ids;
  std::vector<ObservationRecord> folded = changes.folded_observations;
  for (ObservationRecord& row : folded) {
    folded_ids.push_back(row.id);
    row.folded = true;
  }
  CloseObservations(session, map, folded_ids, record.version);
  session.InsertObservations(map.id, changes.added_observations, record.version);
  session.InsertObservations(map.id, folded, record.version);
  session.InsertRemovals(map.id, record.version, changes.removals);
  // Summaries and folding are no observations of their own.
  record.observations_added = static_cast<int64_t>(
      std::count_if(changes.added_observations.begin(), changes.added_observations.end(),
                    [](const ObservationRecord& row) { return !row.summary; }));
  record.observations_removed = static_cast<int64_t>(closed.size());

  std::optional<Extent> extent =
      boundary ? session.ScanExtent(map.id) : internal::Union(map.info.extent, put.extent);
  if (map.info.tree_count == 0) extent.reset();
  internal::StampVersion(map.info, record, std::move(extent));
  session.UpdateMap(map);
  session.InsertVersion(map.id, record);
}

}  // namespace

MapInfo VersionedMapStore::Merge(const std::string& name, const MergeNote& note,
                                 const MergeFunction& merge) {
  internal::CheckName(name);
  MapInfo result;
  backend_->WithWriter([&](StoreSession& session) {
    StoreTransaction transaction(session, TransactionKind::kWrite);
    // The map's write lock is held to the commit: what `merge` reads is the version its changes
    // apply to (no other writer of this map, in this process or another, in between).
    MapRow map = LockMap(session, name);
    CheckExpectedVersion(note, map.info);
    SessionMergeReader reader(session, map);
    const MapChanges changes = merge(reader);
    if (changes.empty()) {
      result = map.info;  // nothing to write: no new version (the transaction rolls back)
      return;
    }
    ApplyChanges(session, map, note, changes);
    CommitWrite(session, transaction, map.info);
    result = map.info;
  });
  return result;
}

}  // namespace forestmap::storage
