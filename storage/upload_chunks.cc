#include "storage/upload_chunks.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "storage/store_steps.h"

namespace forestmap::storage::internal {

using Code = StorageError::Code;

std::string UploadChunks::Label(int64_t index) const {
  return "map '" + map_name_ + "': trees[" + std::to_string(index) + "]";
}

void UploadChunks::Check(const std::vector<TreeRecord>& trees) const {
  std::vector<std::pair<int64_t, int64_t>> ids;  // (id, index in the upload)
  for (size_t i = 0; i < trees.size(); ++i) {
    const TreeRecord& tree = trees[i];
    const int64_t index = staged_ + static_cast<int64_t>(i);
    if (!std::isfinite(tree.x) || !std::isfinite(tree.y) || (tree.z && !std::isfinite(*tree.z)) ||
        (tree.dbh && !std::isfinite(*tree.dbh))) {
      throw StorageError(Code::kInvalidArgument,
                         Label(index) + ": coordinates and DBH must be finite");
    }
    if (tree.id) ids.emplace_back(*tree.id, index);
  }
  std::sort(ids.begin(), ids.end());
  for (size_t k = 1; k < ids.size(); ++k) {
    if (ids[k].first != ids[k - 1].first) continue;
    throw StorageError(Code::kInvalidArgument,
                       Label(ids[k].second) + ".id " + std::to_string(ids[k].first) +
                           " duplicates " + "trees[" + std::to_string(ids[k - 1].second) + "].id");
  }
}

std::vector<int64_t> UploadChunks::Assign(const std::vector<TreeRecord>& trees,
                                          std::optional<int64_t> map_max_id) {
  constexpr int64_t kMax = std::numeric_limits<int64_t>::max();
  // The largest id new ids must not reuse (min(): none).
  int64_t above = std::numeric_limits<int64_t>::min();
  if (mode_ == WriteMode::kAppend && map_max_id) above = *map_max_id;
  size_t auto_count = 0;
  for (const TreeRecord& tree : trees) {
    if (tree.id) {
      above = std::max(above, *tree.id);
    } else {
      ++auto_count;
    }
  }
  if (above == kMax) ids_exhausted_ = true;
  if (above < kMax) next_auto_id_ = std::max(next_auto_id_, above + 1);
  if (auto_count > 0 &&
      (ids_exhausted_ || static_cast<uint64_t>(kMax - next_auto_id_) + 1 < auto_count)) {
    throw StorageError(Code::kInvalidArgument,
                       "map '" + map_name_ + "': no free tree ids left for " +
                           std::to_string(auto_count) + " trees without an id");
  }
  std::vector<int64_t> ids(trees.size());
  for (size_t i = 0; i < trees.size(); ++i) {
    if (trees[i].id) {
      ids[i] = *trees[i].id;
      continue;
    }
    ids[i] = next_auto_id_;
    if (next_auto_id_ == kMax) {
      ids_exhausted_ = true;
    } else {
      ++next_auto_id_;
    }
  }
  return ids;
}

void UploadChunks::Staged(const std::vector<TreeRecord>& trees) {
  staged_ += static_cast<int64_t>(trees.size());
  for (const TreeRecord& tree : trees) {
    confirmed_ += tree.status == TreeStatus::kConfirmed ? 1 : 0;
    extent_ = Union(extent_, Extent{tree.x, tree.y, tree.x, tree.y});
  }
}

VersionRecord UploadChunks::Apply(MapInfo& info, int64_t observations_removed) const {
  const bool replace = mode_ == WriteMode::kReplace;
  VersionRecord record = NextVersion(info, replace ? VersionKind::kReplace : VersionKind::kUpload);
  record.observations_removed = observations_removed;
  StampWrite(info, record, staged_, confirmed_, extent_, replace);
  return record;
}

}  // namespace forestmap::storage::internal
