#include "storage/checks.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <utility>

#include "storage/store_steps.h"

namespace forestmap::storage::internal {

using Code = StorageError::Code;

void CheckName(const std::string& name) {
  const std::string problem = ValidateMapName(name);
  if (problem.empty()) return;
  constexpr size_t kShownChars = 64;
  const std::string shown = name.size() > kShownChars ? name.substr(0, kShownChars) + "..." : name;
  throw StorageError(Code::kInvalidArgument, "invalid map name '" + shown + "': " + problem);
}

void CheckBox(const std::string& name, const Extent& box) {
  if (std::isnan(box.min_x) || std::isnan(box.min_y) || std::isnan(box.max_x) ||
      std::isnan(box.max_y) || box.min_x > box.max_x || box.min_y > box.max_y) {
    throw StorageError(Code::kInvalidArgument,
                       "map '" + name + "': invalid box x [" + std::to_string(box.min_x) + ", " +
                           std::to_string(box.max_x) + "], y [" + std::to_string(box.min_y) + ", " +
                           std::to_string(box.max_y) +
                           "]: bounds must not be NaN and min must not exceed max");
  }
}

std::string TreeLabel(const std::vector<TreeRecord>& trees, size_t index) {
  std::string label = "tree at index " + std::to_string(index);
  if (trees[index].id) label += " (id " + std::to_string(*trees[index].id) + ")";
  return label;
}

BatchSummary CheckBatch(const std::string& map_name, const std::vector<TreeRecord>& trees) {
  BatchSummary summary;
  std::vector<std::pair<int64_t, size_t>> ids;  // (id, index in batch)
  for (size_t i = 0; i < trees.size(); ++i) {
    const TreeRecord& tree = trees[i];
    const auto reject = [&](const char* field, double value) {
      throw StorageError(Code::kInvalidArgument,
                         "map '" + map_name + "': " + TreeLabel(trees, i) + ": " + field +
                             " must be a finite number, got " + std::to_string(value));
    };
    if (!std::isfinite(tree.x)) reject("x", tree.x);
    if (!std::isfinite(tree.y)) reject("y", tree.y);
    if (tree.z && !std::isfinite(*tree.z)) reject("z", *tree.z);
    if (tree.dbh && !std::isfinite(*tree.dbh)) reject("dbh", *tree.dbh);
    summary.extent = Union(summary.extent, Extent{tree.x, tree.y, tree.x, tree.y});
    summary.confirmed += tree.status == TreeStatus::kConfirmed ? 1 : 0;
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
                                                     TreeLabel(changes.put_trees, i) + ": " + what);
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
