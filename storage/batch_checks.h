#pragma once

// Checks of tree batches that every MapStore backend makes before it touches its database.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "storage/map_store.h"

namespace forestmap::storage::internal {

// What a batch of trees to write needs, checked up front.
struct BatchSummary {
  std::optional<int64_t> max_explicit_id;
  size_t auto_id_count = 0;
  std::optional<Extent> extent;
};

// kInvalidArgument naming the tree and field for a non-finite x, y, z or DBH, or naming both
// batch indices for a duplicate id; else the batch's largest explicit id, the count of trees
// without one and the batch's extent.
BatchSummary CheckBatch(const std::string& map_name, const std::vector<TreeRecord>& trees);

// kInvalidArgument for a merge's put_trees without an id, put twice, not finite, or also removed.
void CheckPutTrees(const std::string& map_name, const MapChanges& changes);

}  // namespace forestmap::storage::internal
