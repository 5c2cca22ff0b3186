#pragma once
// Small helpers of the storage tests: records to write and checks of errors.

#include <gtest/gtest.h>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "storage/map_store.h"

namespace forestmap::storage {

inline TreeRecord Tree(std::optional<int64_t> id, double x, double y) {
  TreeRecord tree;
  tree.id = id;
  tree.x = x;
  tree.y = y;
  return tree;
}

// An observation of tree `tree_id` at (x, y) by `source`, seen from 5 m west.
inline ObservationRecord Observation(int64_t tree_id, const std::string& source, double x,
                                     double y) {
  ObservationRecord o;
  o.tree_id = tree_id;
  o.source = source;
  o.frame_id = 7;
  o.detection_index = 3;
  o.x = x;
  o.y = y;
  o.z = 0.5;
  o.weight_xy = 100;
  o.sensor_x = x - 5;
  o.sensor_y = y;
  return o;
}

// `count` trees on a grid of 1 m with 100 columns, ids from `first_id` on (none when negative).
inline std::vector<TreeRecord> Grid(int count, int64_t first_id = -1) {
  std::vector<TreeRecord> trees;
  for (int i = 0; i < count; ++i) {
    TreeRecord tree;
    if (first_id >= 0) tree.id = first_id + i;
    tree.x = i % 100;
    tree.y = i / 100;
    tree.dbh = 0.2;
    trees.push_back(tree);
  }
  return trees;
}

inline std::vector<int64_t> Ids(const std::vector<TreeRecord>& trees) {
  std::vector<int64_t> ids;
  for (const TreeRecord& tree : trees) ids.push_back(*tree.id);
  return ids;
}

// Runs `call`, expects a StorageError with `code` whose message contains `fragment`.
template <typename Call>
void ExpectError(Call call, StorageError::Code code, const std::string& fragment) {
  try {
    call();
    ADD_FAILURE() << "no error; expected one containing '" << fragment << "'";
  } catch (const StorageError& e) {
    EXPECT_EQ(e.code(), code) << e.what();
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
  }
}

// The code of the StorageError `body` throws (a failure when it throws none).
template <typename Body>
StorageError::Code CodeOf(const Body& body) {
  try {
    body();
  } catch (const StorageError& e) {
    return e.code();
  }
  ADD_FAILURE() << "no StorageError";
  return StorageError::Code::kInternal;
}

}  // namespace forestmap::storage
