#include "storage/staged_writes.h"

#include <algorithm>
#include <string>
#include <utility>

namespace forestmap::storage {

using Code = StorageError::Code;

namespace {

class InMemoryUpload final : public TreeUpload {
 public:
  InMemoryUpload(MapStore& store, std::string name, UploadPlan plan)
      : store_(store), name_(std::move(name)), plan_(std::move(plan)) {}

  void Append(const std::vector<TreeRecord>& trees) override {
    trees_.insert(trees_.end(), trees.begin(), trees.end());
  }

  MapInfo Commit() override {
    MapInfo info;
    if (plan_.create_map) info = store_.CreateMap(name_, plan_.description, plan_.crs);
    if (!trees_.empty() || plan_.mode == WriteMode::kReplace || !plan_.create_map) {
      info = store_.WriteTrees(name_, trees_, plan_.mode);
    }
    trees_ = {};
    return info;
  }

  int64_t staged() const override { return static_cast<int64_t>(trees_.size()); }

 private:
  MapStore& store_;
  std::string name_;
  UploadPlan plan_;
  std::vector<TreeRecord> trees_;
};

bool Inside(const TreeRecord& tree, const Extent& box) {
  return tree.x >= box.min_x && tree.x <= box.max_x && tree.y >= box.min_y && tree.y <= box.max_y;
}

}  // namespace

std::unique_ptr<TreeUpload> MemoryUpload(MapStore& store, const std::string& name,
                                         const UploadPlan& plan) {
  if (plan.boundary) {
    throw StorageError(Code::kInvalidArgument,
                       "map '" + name + "': this store keeps no survey boundaries");
  }
  if (plan.create_map) {
    try {
      store.GetMap(name);
      throw StorageError(Code::kAlreadyExists, "map '" + name + "' already exists");
    } catch (const StorageError& e) {
      if (e.code() != Code::kNotFound) throw;
    }
  } else {
    store.GetMap(name);  // kNotFound before the client sends its trees
  }
  return std::make_unique<InMemoryUpload>(store, name, plan);
}

Boundary MapStore::ReadBoundary(const std::string& name, int64_t version) {
  return ReadMapVersion(name, version).boundary;
}

std::vector<std::string> MapStore::ReadAttributeColumns(const std::string& name, int64_t version) {
  return ReadMapVersion(name, version).attribute_columns;
}

std::vector<TreeRecord> PageOfSnapshot(MapStore& store, const std::string& name,
                                       const TreePageQuery& query) {
  const MapSnapshot snapshot = store.ReadMapVersion(name, query.version);
  if (query.created_unix_ms != 0 && snapshot.info.created_unix_ms != query.created_unix_ms) {
    throw StorageError(Code::kConflict, "map '" + name + "' was deleted and created again");
  }
  std::vector<TreeRecord> page;
  for (const TreeRecord& tree : snapshot.trees) {
    if (query.after_id && *tree.id <= *query.after_id) continue;
    if (query.box && !Inside(tree, *query.box)) continue;
    page.push_back(tree);
    if (static_cast<int64_t>(page.size()) >= query.limit) break;
  }
  return page;
}

std::unique_ptr<TreeUpload> MapStore::BeginUpload(const std::string& name, const UploadPlan& plan) {
  return MemoryUpload(*this, name, plan);
}

std::vector<TreeRecord> MapStore::ReadTreesPage(const std::string& name,
                                                const TreePageQuery& query) {
  return PageOfSnapshot(*this, name, query);
}

}  // namespace forestmap::storage
