#include "storage/batch_checks.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <utility>

#include "storage/sqlite_map_store_internal.h"  // backend-neutral helpers: TreeLabel, Union

namespace forestmap::storage::internal {

using Code = StorageError::Code;

BatchSummary CheckBatch(const std::string& map_name, const std::vector<TreeRecord>& trees) {
  BatchSummary summary;
  std::vector<std::pair<int64_t, size_t>> ids;  // (id, index in batch)
  for (size_t i = 0; i < trees.size(); ++i) {
    const TreeRecord& tree = trees[i];
    const auto reject = [&](const char* field, double value) {
      throw StorageError(Code::kInvalidArgument,
                         "map '" + map_name + "': " + internal::TreeLabel(trees, i) + ": " + field +
                             " must be a finite number, got " + std::to_string(value));
    };
    if (!std::isfinite(tree.x)) reject("x", tree.x);
    if (!std::isfinite(tree.y)) reject("y", tree.y);
    if (tree.z && !std::isfinite(*tree.z)) reject("z", *tree.z);
    if (tree.dbh && !std::isfinite(*tree.dbh)) reject("dbh", *tree.dbh);
    summary.extent = internal::Union(summary.extent, Extent{tree.x, tree.y, tree.x, tree.y});
    if (tree.id) {
      ids.emplace_back(*tree.id, i);
    } else {
      ++summary.auto_id_count;
    }
  }
  std::sort(ids.begin(), ids.end());
  for (size_t k = 1; k < ids.size(); ++k) {
    if (ids[k].first == ids[k - 1].first) {
      throw StorageError(Code::kInvalidArgument, "map '" + map_name + "': duplicate tree id " +
                                                     std::to_string(ids[k].first) + " at indices " +
                                                     std::to_string(ids[k - 1].second) + " and " +
                                                     std::to_string(ids[k].second) +
                                                     " of the batch");
    }
  }
  if (!ids.empty()) summary.max_explicit_id = ids.back().first;
  return summary;
}

void CheckPutTrees(const std::string& map_name, const MapChanges& changes) {
  std::set<int64_t> ids;
  for (size_t i = 0; i < changes.put_trees.size(); ++i) {
    const TreeRecord& tree = changes.put_trees[i];
    const auto fail = [&](const std::string& what) {
      throw StorageError(Code::kInvalidArgument, "map '" + map_name + "': merge: " +
                                                     internal::TreeLabel(changes.put_trees, i) +
                                                     ": " + what);
    };
    if (!tree.id) fail("a merged tree needs an id");
    if (!ids.insert(*tree.id).second) fail("the id is put twice");
    if (!std::isfinite(tree.x) || !std::isfinite(tree.y) || (tree.z && !std::isfinite(*tree.z)) ||
        (tree.dbh && !std::isfinite(*tree.dbh))) {
      fail("coordinates and DBH must be finite");
    }
  }
  for (const int64_t id : changes.removed_trees) {
    if (ids.count(id) != 0) {
      throw StorageError(
          Code::kInvalidArgument,
          "map '" + map_name + "': merge: tree " + std::to_string(id) + " is both put and removed");
    }
  }
}

}  // namespace forestmap::storage::internal
