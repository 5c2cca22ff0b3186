#pragma once
// What every store's staged upload (storage/staged_writes.h) does the same way: checks of each
// chunk, ids for trees without one, and the running counts and extent of what was staged.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "storage/map_store.h"

namespace forestmap::storage::internal {

class UploadChunks {
 public:
  UploadChunks(std::string map_name, WriteMode mode)
      : map_name_(std::move(map_name)), mode_(mode) {}

  // kInvalidArgument naming "trees[k]" (k: index in the upload) for a non-finite x, y, z or DBH
  // and for two trees of the chunk with the same id.
  void Check(const std::vector<TreeRecord>& trees) const;
  // Ids of the chunk in order: explicit ones, then the next free ones above every explicit id
  // sent so far and, when appending, above `map_max_id` (the map's largest current id).
  // kInvalidArgument when no ids are left.
  std::vector<int64_t> Assign(const std::vector<TreeRecord>& trees,
                              std::optional<int64_t> map_max_id);
  // Counts a chunk that was staged.
  void Staged(const std::vector<TreeRecord>& trees);
  // Makes `info` the map after the staged trees were committed as its next version (counts,
  // extent, version, time) and returns that version's history entry. `observations_removed`:
  // the observation rows a replace closed.
  VersionRecord Apply(MapInfo& info, int64_t observations_removed) const;

  // "map 'x': trees[k]" of the upload, for messages.
  std::string Label(int64_t index) const;
  int64_t staged() const { return staged_; }

 private:
  std::string map_name_;
  WriteMode mode_;
  int64_t staged_ = 0;
  int64_t confirmed_ = 0;
  std::optional<Extent> extent_;
  int64_t next_auto_id_ = 1;    // the id of the next tree without one
  bool ids_exhausted_ = false;  // INT64_MAX was given or sent: no ids left for trees without one
};

}  // namespace forestmap::storage::internal
