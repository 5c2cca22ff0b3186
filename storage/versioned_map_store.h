#pragma once
// MapStore written once over a StoreBackend (storage/store_backend.h): maps, trees, versions,
// merges, restore, prune, exactly-once writes, staged uploads and exports by pages, with the same
// checks, errors and bookkeeping on every database. SqliteMapStore (storage/sqlite/store.h) and
// PostgresMapStore (storage/postgres/store.h) derive from it only to open their backend.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "storage/map_store.h"
#include "storage/store_backend.h"

namespace forestmap::storage {

// Every version of a map stays readable: tree and observation rows carry the version range
// [valid_from, valid_to) they belong to, a change closes the current rows it replaces and inserts
// new ones, and map_versions holds the history. A write that cannot change anything (kAppend of
// no trees, kReplace of no trees on an empty map, a merge without changes) makes no version.
// TreesInBox throws kInvalidArgument for a NaN bound or min > max; infinite bounds are allowed.
// Thread-safety: as MapStore; how calls share connections is the backend's (see its shell).
class VersionedMapStore : public MapStore {
 public:
  explicit VersionedMapStore(std::unique_ptr<StoreBackend> backend);
  ~VersionedMapStore() override;
  VersionedMapStore(const VersionedMapStore&) = delete;
  VersionedMapStore& operator=(const VersionedMapStore&) = delete;

  MapInfo CreateMap(const std::string& name, const std::string& description,
                    const std::string& crs) override;
  std::vector<MapInfo> ListMaps() override;
  MapInfo GetMap(const std::string& name) override;
  void DeleteMap(const std::string& name) override;
  MapInfo WriteTrees(const std::string& name, const std::vector<TreeRecord>& trees,
                     WriteMode mode) override;
  MapSnapshot ReadMap(const std::string& name) override;
  std::vector<TreeRecord> TreesInBox(const std::string& name, const Extent& box) override;

  MapSnapshot ReadMapVersion(const std::string& name, int64_t version) override;
  Boundary ReadBoundary(const std::string& name, int64_t version) override;
  std::vector<std::string> ReadAttributeColumns(const std::string& name, int64_t version) override;
  std::vector<TreeRemoval> ListRemovals(const std::string& name, int64_t after_version) override;
  std::vector<VersionRecord> ListVersions(const std::string& name, int64_t limit) override;
  MapInfo RestoreVersion(const std::string& name, int64_t version) override;
  MapInfo Merge(const std::string& name, const MergeNote& note,
                const MergeFunction& merge) override;
  PruneResult PruneVersions(const std::string& name, int64_t keep) override;
  std::optional<StoredRequest> FindRequest(const std::string& request_id) override;
  std::unique_ptr<TreeUpload> BeginUpload(const std::string& name, const UploadPlan& plan) override;
  // One short read transaction per page, through the index of current or closed rows.
  std::vector<TreeRecord> ReadTreesPage(const std::string& name,
                                        const TreePageQuery& query) override;
  std::string OpenWarning() const override { return backend_->OpenWarning(); }

 private:
  std::unique_ptr<StoreBackend> backend_;
};

}  // namespace forestmap::storage
