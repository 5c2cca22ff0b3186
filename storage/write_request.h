#pragma once
// The client request a write belongs to, for exactly-once writes and deadlines.
//
// The server opens a WriteRequestScope on the thread that calls a MapStore write method
// (CreateMap, DeleteMap, WriteTrees, RestoreVersion, Merge, PruneVersions). Every backend honours
// the scope inside that write's transaction, just before it commits:
//   1. when the deadline has passed, nothing is committed: StorageError kDeadlineExceeded;
//   2. when the request has an id, the answer `encode(info)` (info: the map as the write leaves
//      it) is stored under the id IN THE SAME TRANSACTION, so the write and its record commit
//      together or not at all. An id that is already stored fails the write with kConflict
//      (a concurrent duplicate); MapStore::FindRequest then returns the first answer.
// A write that changes nothing (and so commits nothing) stores no record.

#include <chrono>
#include <cstdint>
#include <functional>
#include <string>

namespace forestmap::storage {

struct MapInfo;

struct WriteRequest {
  std::string id;   // the client's request id; empty: none (no record is stored)
  std::string rpc;  // the call, e.g. "UploadTrees": an id is never answered for another call
  // What the id is bound to, stored with the answer (opaque here: the server's hash of the call,
  // map, caller and request content); empty: nothing but `rpc`.
  std::string fingerprint;
  // The encoded answer of the call for the map state the write leaves (called inside the
  // transaction, so it must not call the store).
  std::function<std::string(const MapInfo&)> encode;
  std::chrono::system_clock::time_point deadline = std::chrono::system_clock::time_point::max();
};

// A stored answer (MapStore::FindRequest).
struct StoredRequest {
  std::string rpc;
  std::string response;  // what WriteRequest::encode returned
  int64_t created_unix_ms = 0;
  std::string fingerprint;  // WriteRequest::fingerprint; empty for answers stored before it
};

// Makes `request` the current write request of this thread for the scope's lifetime (not
// nestable: a second scope on the same thread replaces the first until it ends).
class WriteRequestScope {
 public:
  explicit WriteRequestScope(const WriteRequest& request);
  ~WriteRequestScope();
  WriteRequestScope(const WriteRequestScope&) = delete;
  WriteRequestScope& operator=(const WriteRequestScope&) = delete;

 private:
  const WriteRequest* previous_;
};

// The current write request of this thread, or null.
const WriteRequest* CurrentWriteRequest();

// For the stores, inside a write's transaction: kConflict when the request log already held
// `request`'s id (a concurrent call applied it), and kDeadlineExceeded when its deadline has
// passed (checked last, as close to COMMIT as possible).
[[noreturn]] void ThrowAppliedConcurrently(const WriteRequest& request);
void CheckDeadlineBeforeCommit(const WriteRequest& request);

}  // namespace forestmap::storage
