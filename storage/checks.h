#pragma once
// Checks of a call's arguments that every MapStore backend makes before it touches its database:
// map names, boxes, batches of trees to write and a merge's changes. Not a public API.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "storage/map_store.h"

namespace forestmap::storage::internal {

// kInvalidArgument naming the rule for a name ValidateMapName refuses (the name cut to 64 chars).
void CheckName(const std::string& name);
// kInvalidArgument for a NaN bound or min > max.
void CheckBox(const std::string& name, const Extent& box);
// "tree at index i (id n)" of a batch, for messages.
std::string TreeLabel(const std::vector<TreeRecord>& trees, size_t index);

// What a batch of trees to write needs, checked up front.
struct BatchSummary {
  std::optional<int64_t> max_explicit_id;
  size_t auto_id_count = 0;
  int64_t confirmed = 0;  // trees with status kConfirmed
  std::optional<Extent> extent;
};

// kInvalidArgument naming the tree and field for a non-finite x, y, z or DBH, or naming both
// batch indices for a duplicate id; else the batch's largest explicit id, the count of trees
// without one and the batch's extent.
BatchSummary CheckBatch(const std::string& map_name, const std::vector<TreeRecord>& trees);

// kInvalidArgument for a merge's put_trees without an id, put twice, not finite, or also removed.
void CheckPutTrees(const std::string& map_name, const MapChanges& changes);

}  // namespace forestmap::storage::internal
