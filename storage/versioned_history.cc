// VersionedMapStore: the history of a map (reading an older version, listing versions), restoring
// a version and pruning the history.

#include <set>
#include <string>
#include <vector>

#include "storage/attribute_json.h"
#include "storage/boundary_json.h"
#include "storage/checks.h"
#include "storage/store_steps.h"
#include "storage/versioned_map_store.h"

namespace forestmap::storage {

using Code = StorageError::Code;

namespace {

// kInvalidArgument for a negative version number (0 reads the current version).
void CheckVersionNumber(const std::string& name, int64_t version) {
  if (version < 0) {
    throw StorageError(Code::kInvalidArgument,
                       "map '" + name + "': version " + std::to_string(version) + " is negative");
  }
}

// The map as it was at `record.version`, whose trees were `trees`: the current map's name,
// description and CRS with that version's number, time, counts and extent.
MapInfo InfoAtVersion(MapInfo current, const VersionRecord& record,
                      const std::vector<TreeRecord>& trees) {
  MapInfo info = std::move(current);
  info.version = record.version;
  info.updated_unix_ms = record.created_unix_ms;
  info.tree_count = static_cast<int64_t>(trees.size());
  info.confirmed_count = 0;
  info.extent.reset();
  for (const TreeRecord& tree : trees) {
    info.confirmed_count += tree.status == TreeStatus::kConfirmed ? 1 : 0;
    info.extent = internal::Union(info.extent, Extent{tree.x, tree.y, tree.x, tree.y});
  }
  return info;
}

// StampVersion for restoring `old` as the version after `info`'s: counts of `old`,
// `extent` scanned after the restore.
void StampRestore(MapInfo& info, VersionRecord& record, const VersionRecord& old,
                  std::optional<Extent> extent) {
  record.version = info.version + 1;
  record.kind = VersionKind::kRestore;
  record.restored_from = old.version;
  info.tree_count = old.tree_count;
  info.confirmed_count = old.confirmed_count;
  internal::StampVersion(info, record, std::move(extent));
}

// Restore's tree rows: rows valid at `version` but closed since come back as copies valid from
// `next`; current rows added after `version` are closed. Counts go into `record`.
void RestoreTrees(StoreSession& session, const MapRow& map, int64_t version, int64_t next,
                  VersionRecord& record) {
  const std::vector<TreeRecord> copies = session.ClosedTreesAt(map, version);
  const std::vector<int64_t> closed_ids = session.CloseTreesAddedAfter(map.id, version, next);
  const std::set<int64_t> closed(closed_ids.begin(), closed_ids.end());
  std::vector<int64_t> ids;
  ids.reserve(copies.size());
  for (const TreeRecord& tree : copies) {
    ids.push_back(*tree.id);
    ++(closed.count(*tree.id) ? record.trees_updated : record.trees_added);
  }
  record.trees_removed = static_cast<int64_t>(closed.size()) - record.trees_updated;
  session.InsertTrees(map, copies, ids, next);
}

// Restore's observation rows, the same way.
void RestoreObservations(StoreSession& session, const MapRow& map, int64_t version, int64_t next,
                         VersionRecord& record) {
  const std::vector<ObservationRecord> copies = session.ClosedObservationsAt(map.id, version);
  record.observations_removed = session.CloseObservationsAddedAfter(map.id, version, next);
  session.InsertObservations(map.id, copies, next);
  record.observations_added = static_cast<int64_t>(copies.size());
}

// What `read(session, map id, version)` stores for version `version` of map `name` (0: the
// current one), read in one transaction after checking that the map and the version exist.
template <typename Read>
std::string ReadVersionText(StoreBackend& backend, const std::string& name, int64_t version,
                            const Read& read) {
  internal::CheckName(name);
  CheckVersionNumber(name, version);
  std::string text;
  backend.WithReader([&](StoreSession& session) {
    StoreTransaction transaction(session, TransactionKind::kRead);
    const MapRow map = RequireMap(session, name);
    if (version != 0 && version != map.info.version) RequireVersion(session, map, version);
    text = read(session, map.id, version == 0 ? map.info.version : version);
    transaction.Commit();
  });
  return text;
}

}  // namespace

MapSnapshot VersionedMapStore::ReadMapVersion(const std::string& name, int64_t version) {
  internal::CheckName(name);
  CheckVersionNumber(name, version);
  MapSnapshot snapshot;
  backend_->WithReader([&](StoreSession& session) {
    // Info and trees of one version.
    StoreTransaction transaction(session, TransactionKind::kRead);
    const MapRow map = RequireMap(session, name);
    snapshot.info = map.info;
    if (version == 0 || version == map.info.version) {
      snapshot.trees = session.CurrentTrees(map);
      snapshot.boundary =
          internal::DecodeBoundary(name, session.BoundaryAt(map.id, map.info.version));
      snapshot.attribute_columns =
          internal::DecodeColumnOrder(name, session.ColumnsAt(map.id, map.info.version));
      transaction.Commit();
      return;
    }
    const VersionRecord record = RequireVersion(session, map, version);
    snapshot.trees = session.TreesAtVersion(map, version);
    snapshot.boundary = internal::DecodeBoundary(name, session.BoundaryAt(map.id, version));
    snapshot.attribute_columns =
        internal::DecodeColumnOrder(name, session.ColumnsAt(map.id, version));
    transaction.Commit();
    snapshot.info = InfoAtVersion(map.info, record, snapshot.trees);
    snapshot.info.has_boundary = !snapshot.boundary.empty();
  });
  return snapshot;
}

Boundary VersionedMapStore::ReadBoundary(const std::string& name, int64_t version) {
  return internal::DecodeBoundary(
      name, ReadVersionText(*backend_, name, version,
                            [](StoreSession& session, int64_t map_id, int64_t at) {
                              return session.BoundaryAt(map_id, at);
                            }));
}

std::vector<std::string> VersionedMapStore::ReadAttributeColumns(const std::string& name,
                                                                 int64_t version) {
  return internal::DecodeColumnOrder(
      name, ReadVersionText(*backend_, name, version,
                            [](StoreSession& session, int64_t map_id, int64_t at) {
                              return session.ColumnsAt(map_id, at);
                            }));
}

std::vector<TreeRemoval> VersionedMapStore::ListRemovals(const std::string& name,
                                                         int64_t after_version) {
  internal::CheckName(name);
  std::vector<TreeRemoval> removals;
  backend_->WithReader([&](StoreSession& session) {
    StoreTransaction transaction(session, TransactionKind::kRead);
    removals = session.RemovalsAfter(RequireMap(session, name).id, after_version);
    transaction.Commit();
  });
  return removals;
}

std::vector<VersionRecord> VersionedMapStore::ListVersions(const std::string& name, int64_t limit) {
  internal::CheckName(name);
  std::vector<VersionRecord> versions;
  backend_->WithReader([&](StoreSession& session) {
    StoreTransaction transaction(session, TransactionKind::kRead);
    const MapRow map = RequireMap(session, name);
    const std::vector<int64_t> numbers = session.NewestVersions(map.id, limit);
    for (auto it = numbers.rbegin(); it != numbers.rend(); ++it) {
      versions.push_back(RequireVersion(session, map, *it));
    }
    transaction.Commit();
  });
  return versions;
}

// A new version whose trees and observation rows are those of an older one. Rows valid at that
// version but no longer current come back as copies; current rows the version did not have are
// closed; rows valid at both simply stay.
MapInfo VersionedMapStore::RestoreVersion(const std::string& name, int64_t version) {
  internal::CheckName(name);
  MapInfo result;
  backend_->WithWriter([&](StoreSession& session) {
    StoreTransaction transaction(session, TransactionKind::kWrite);
    MapRow map = LockMap(session, name);
    const VersionRecord old = RequireVersion(session, map, version);
    const int64_t next = map.info.version + 1;
    VersionRecord record;
    RestoreTrees(session, map, version, next, record);
    RestoreObservations(session, map, version, next, record);
    const std::string boundary = session.BoundaryAt(map.id, version);
    if (boundary != session.BoundaryAt(map.id, map.info.version)) {
      session.InsertBoundary(map.id, next, boundary);
    }
    map.info.has_boundary = !boundary.empty();
    const std::string columns = session.ColumnsAt(map.id, version);
    if (columns != session.ColumnsAt(map.id, map.info.version)) {
      session.InsertColumns(map.id, next, columns);
    }
    StampRestore(map.info, record, old, session.ScanExtent(map.id));
    session.UpdateMap(map);
    session.InsertVersion(map.id, record);
    CommitWrite(session, transaction, map.info);
    result = map.info;
  });
  return result;
}

PruneResult VersionedMapStore::PruneVersions(const std::string& name, int64_t keep) {
  internal::CheckName(name);
  if (keep < 1) {
    throw StorageError(Code::kInvalidArgument,
                       "keep is " + std::to_string(keep) + "; at least the current version stays");
  }
  PruneResult result;
  FreeRoom(*backend_, [&](StoreSession& session) {
    StoreTransaction transaction(session, TransactionKind::kWrite);
    const MapRow map = LockMap(session, name);
    result.info = map.info;
    const int64_t first_kept = map.info.version - keep + 1;
    if (first_kept <= 1) return;  // nothing older than what is kept
    const PrunedRows pruned = session.PruneBefore(map.id, first_kept);
    result.tree_rows_removed = pruned.trees;
    result.observation_rows_removed = pruned.observations;
    result.versions_removed = pruned.versions;
    CommitWrite(session, transaction, map.info);
  });
  return result;
}

}  // namespace forestmap::storage
