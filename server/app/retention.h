#pragma once
// History retention: a map keeps its newest versions readable and drops the older ones
// (MapStore::PruneVersions), on demand (the PruneVersions call) or, with forestmapd
// --keep-versions N, after every write. One implementation for every caller: the unary writes
// and the upload stream of the gRPC service, and PruneVersions itself.

#include <cstdint>
#include <string>

#include "server/app/errors.h"
#include "storage/map_store.h"

namespace forestmap::server {

// ValidationError unless keep >= 1: the current version always stays.
void CheckKeep(int64_t keep);

// Drops the history of `map` beyond its newest `keep` versions. Throws as CheckKeep, and what the
// store throws (storage::StorageError kNotFound for an unknown map, faults of the database).
storage::PruneResult PruneHistory(storage::MapStore& store, const std::string& map, int64_t keep);

// The --keep-versions policy, applied after each committed write.
// Thread-safety: AfterWrite may be called concurrently (the store serializes the prunes).
class RetentionPolicy {
 public:
  // keep_versions 0: every version stays (AfterWrite does nothing). `store` must outlive the
  // policy. Throws std::invalid_argument for keep_versions < 0 or an empty report.
  RetentionPolicy(storage::MapStore& store, int64_t keep_versions, FaultReport report);

  // Prunes `map` to its newest keep_versions versions. A failure is not the caller's answer (the
  // write it follows has committed and stands), so it is caught, whatever it is, and goes to the
  // report: "retention of map "NAME" failed (the write stands): WHY". Returns false then, true
  // when it pruned or had nothing to do. Throws only what the report throws.
  bool AfterWrite(const std::string& map) const;

  int64_t keep_versions() const { return keep_versions_; }

 private:
  storage::MapStore& store_;
  int64_t keep_versions_;
  FaultReport report_;
};

}  // namespace forestmap::server
