// VersionedMapStore: maps, writes of whole batches, reads of the current map, exports by pages and
// the request log. Versions, restore and prune are in versioned_history.cc, merges in
// versioned_merge.cc.

#include "storage/versioned_map_store.h"

#include <optional>
#include <string>
#include <utility>

#include "storage/checks.h"
#include "storage/store_steps.h"

namespace forestmap::storage {

using Code = StorageError::Code;

VersionedMapStore::VersionedMapStore(std::unique_ptr<StoreBackend> backend)
    : backend_(std::move(backend)) {}

VersionedMapStore::~VersionedMapStore() = default;

// ---- Maps ----

MapInfo VersionedMapStore::CreateMap(const std::string& name, const std::string& description,
                                     const std::string& crs) {
  internal::CheckName(name);
  const MapInfo info = internal::NewMapInfo(name, description, crs);
  backend_->WithWriter([&](StoreSession& session) {
    StoreTransaction transaction(session, TransactionKind::kWrite);
    int64_t id = 0;
    try {
      id = session.InsertMap(info);
    } catch (const StorageError& e) {
      if (e.code() != Code::kAlreadyExists) throw;  // UNIQUE(name)
      throw StorageError(Code::kAlreadyExists, "map '" + name + "' already exists");
    }
    session.InsertVersion(id, internal::CreationRecord(info));
    CommitWrite(session, transaction, info);
  });
  return info;
}

std::vector<MapInfo> VersionedMapStore::ListMaps() {
  std::vector<MapInfo> maps;
  backend_->WithReader([&](StoreSession& session) { maps = session.ListMaps(); });
  return maps;
}

MapInfo VersionedMapStore::GetMap(const std::string& name) {
  internal::CheckName(name);
  MapInfo info;
  backend_->WithReader([&](StoreSession& session) { info = RequireMap(session, name).info; });
  return info;
}

void VersionedMapStore::DeleteMap(const std::string& name) {
  internal::CheckName(name);
  backend_->WithWriter([&](StoreSession& session) {
    StoreTransaction transaction(session, TransactionKind::kWrite);
    const MapRow map = LockMap(session, name);
    session.DeleteMap(map);
    CommitWrite(session, transaction, map.info);
  });
}

// ---- Trees ----

MapInfo VersionedMapStore::WriteTrees(const std::string& name, const std::vector<TreeRecord>& trees,
                                      WriteMode mode) {
  internal::CheckName(name);
  const internal::BatchSummary batch = internal::CheckBatch(name, trees);
  MapInfo result;
  backend_->WithWriter([&](StoreSession& session) {
    StoreTransaction transaction(session, TransactionKind::kWrite);
    MapRow map = LockMap(session, name);
    const bool replace = mode == WriteMode::kReplace;
    if (internal::WriteChangesNothing(trees, replace, map.info)) {
      result = map.info;  // nothing can change: keep the version
      return;
    }
    VersionRecord record =
        internal::NextVersion(map.info, replace ? VersionKind::kReplace : VersionKind::kUpload);
    std::optional<int64_t> max_id = batch.max_explicit_id;
    if (replace) {
      record.trees_removed = map.info.tree_count;
      record.observations_removed = session.CloseAllRows(map.id, record.version);
    } else if (const std::optional<int64_t> max_current = session.MaxCurrentTreeId(map.id)) {
      max_id = internal::MaxId(max_id, *max_current);
    }
    const std::vector<int64_t> ids = internal::AssignIds(name, trees, max_id, batch.auto_id_count);
    session.InsertTrees(map, trees, ids, record.version);
    internal::StampWrittenBatch(map.info, record, trees, batch, replace);
    session.UpdateMap(map);
    session.InsertVersion(map.id, record);
    CommitWrite(session, transaction, map.info);
    result = map.info;
  });
  return result;
}

MapSnapshot VersionedMapStore::ReadMap(const std::string& name) { return ReadMapVersion(name, 0); }

std::vector<TreeRecord> VersionedMapStore::TreesInBox(const std::string& name, const Extent& box) {
  internal::CheckName(name);
  internal::CheckBox(name, box);
  std::vector<TreeRecord> trees;
  backend_->WithReader([&](StoreSession& session) {
    StoreTransaction transaction(session, TransactionKind::kRead);
    const MapRow map = RequireMap(session, name);
    trees = session.TreesInBox(map, box);
    transaction.Commit();
  });
  return trees;
}

// ---- Bounded memory ----

std::unique_ptr<TreeUpload> VersionedMapStore::BeginUpload(const std::string& name,
                                                           const UploadPlan& plan) {
  internal::CheckName(name);
  return backend_->BeginUpload(name, plan);
}

std::vector<TreeRecord> VersionedMapStore::ReadTreesPage(const std::string& name,
                                                         const TreePageQuery& query) {
  internal::CheckName(name);
  internal::CheckPageQuery(name, query);
  std::vector<TreeRecord> trees;
  backend_->WithReader([&](StoreSession& session) {
    StoreTransaction transaction(session, TransactionKind::kRead);  // the page and its checks agree
    const MapRow map = RequireMap(session, name);
    internal::CheckPageTarget(name, query, map.info);
    if (query.version == map.info.version) {
      trees = session.CurrentPage(map, query);
    } else {
      RequireVersion(session, map, query.version);  // kNotFound once pruned: its rows may be gone
      // Rows of the version that are still current, then closed rows that were valid then: each
      // query walks its index in id order and stops after `limit` matches.
      trees = session.CurrentPage(map, query);
      std::vector<TreeRecord> closed = session.ClosedPage(map, query);
      trees.insert(trees.end(), std::make_move_iterator(closed.begin()),
                   std::make_move_iterator(closed.end()));
      internal::SortAndTrimPage(trees, query.limit);
    }
    transaction.Commit();
  });
  return trees;
}

// ---- Exactly-once writes ----

std::optional<StoredRequest> VersionedMapStore::FindRequest(const std::string& request_id) {
  std::optional<StoredRequest> found;
  backend_->WithReader([&](StoreSession& session) { found = session.FindRequest(request_id); });
  return found;
}

}  // namespace forestmap::storage
