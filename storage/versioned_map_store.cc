// VersionedMapStore: maps, writes of whole batches, reads of the current map, exports by pages and
// the request log. Versions, restore and prune are in versioned_history.cc, merges in
// versioned_merge.cc.

#include "storage/versioned_map_store.h"

#include <algorithm>
#include <limits>
#include <optional>
#include <string>
#include <utility>

#include "storage/checks.h"
#include "storage/store_steps.h"

namespace forestmap::storage {

using Code = StorageError::Code;

namespace {

// Whether WriteTrees of `trees` changes nothing (no version is made): nothing to append, or a
// replace of an empty map by nothing.
bool WriteChangesNothing(const std::vector<TreeRecord>& trees, bool replace, const MapInfo& map) {
  return trees.empty() && (!replace || map.tree_count == 0);
}

// The larger of an optional id and `id`.
std::optional<int64_t> MaxId(std::optional<int64_t> max_id, int64_t id) {
  return std::max(max_id.value_or(std::numeric_limits<int64_t>::min()), id);
}

// Ids of the batch in batch order: explicit ones, then the next free ones above `max_id` (and
// at least 1) for the `auto_count` trees without one. kInvalidArgument when they run out.
std::vector<int64_t> AssignIds(const std::string& map_name, const std::vector<TreeRecord>& trees,
                               std::optional<int64_t> max_id, size_t auto_count) {
  const int64_t above = std::max<int64_t>(max_id.value_or(0), 0);
  constexpr int64_t kMax = std::numeric_limits<int64_t>::max();
  if (auto_count > 0 && static_cast<uint64_t>(kMax - above) < auto_count) {
    throw StorageError(Code::kInvalidArgument,
                       "map '" + map_name + "': no free tree ids left above " +
                           std::to_string(above) + " for " + std::to_string(auto_count) +
                           " trees without an id");
  }
  std::vector<int64_t> ids(trees.size());
  int64_t assigned = 0;  // counted apart so the last id may be INT64_MAX without overflow
  for (size_t i = 0; i < trees.size(); ++i)
    ids[i] = trees[i].id ? *trees[i].id : above + ++assigned;
  return ids;
}

// kInvalidArgument for a version or limit below 1, or an invalid box.
void CheckPageQuery(const std::string& name, const TreePageQuery& query) {
  if (query.version < 1 || query.limit < 1) {
    throw StorageError(Code::kInvalidArgument,
                       "map '" + name + "': a page needs version >= 1 and limit >= 1");
  }
  if (query.box) internal::CheckBox(name, *query.box);
}

// kConflict when the map was created again since the export began, kNotFound for a version the
// map does not have yet.
void CheckPageTarget(const std::string& name, const TreePageQuery& query, const MapInfo& map) {
  if (query.created_unix_ms != 0 && map.created_unix_ms != query.created_unix_ms) {
    throw StorageError(Code::kConflict, "map '" + name +
                                            "' was deleted and created again during the "
                                            "export; retry");
  }
  if (query.version > map.version) {
    throw StorageError(Code::kNotFound, "map '" + name + "' has no version " +
                                            std::to_string(query.version) + " yet");
  }
}

// Sorts a page read from current and closed rows by id and keeps the first `limit`.
void SortAndTrimPage(std::vector<TreeRecord>& trees, int64_t limit) {
  std::sort(trees.begin(), trees.end(),
            [](const TreeRecord& a, const TreeRecord& b) { return *a.id < *b.id; });
  if (static_cast<int64_t>(trees.size()) > limit) trees.resize(static_cast<size_t>(limit));
}

}  // namespace

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
  FreeRoom(*backend_, [&](StoreSession& session) {
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
    if (WriteChangesNothing(trees, replace, map.info)) {
      result = map.info;  // nothing can change: keep the version
      return;
    }
    VersionRecord record =
        internal::NextVersion(map.info, replace ? VersionKind::kReplace : VersionKind::kUpload);
    std::optional<int64_t> max_id = batch.max_explicit_id;
    if (replace) {
      record.observations_removed = session.CloseAllRows(map.id, record.version);
    } else if (const std::optional<int64_t> max_current = session.MaxCurrentTreeId(map.id)) {
      max_id = MaxId(max_id, *max_current);
    }
    const std::vector<int64_t> ids = AssignIds(name, trees, max_id, batch.auto_id_count);
    session.InsertTrees(map, trees, ids, record.version);
    internal::StampWrite(map.info, record, static_cast<int64_t>(trees.size()), batch.confirmed,
                         batch.extent, replace);
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
  CheckPageQuery(name, query);
  std::vector<TreeRecord> trees;
  backend_->WithReader([&](StoreSession& session) {
    StoreTransaction transaction(session, TransactionKind::kRead);  // the page and its checks agree
    const MapRow map = RequireMap(session, name);
    CheckPageTarget(name, query, map.info);
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
      SortAndTrimPage(trees, query.limit);
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
