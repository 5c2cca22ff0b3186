#include "storage/write_request.h"

#include <chrono>

#include "storage/map_store.h"

namespace forestmap::storage {
namespace {

thread_local const WriteRequest* current_request = nullptr;

}  // namespace

WriteRequestScope::WriteRequestScope(const WriteRequest& request) : previous_(current_request) {
  current_request = &request;
}

WriteRequestScope::~WriteRequestScope() { current_request = previous_; }

const WriteRequest* CurrentWriteRequest() { return current_request; }

void ThrowAppliedConcurrently(const WriteRequest& request) {
  throw StorageError(StorageError::Code::kConflict,
                     "request id '" + request.id +
                         "' was applied by a concurrent call; nothing was written twice");
}

void CheckDeadlineBeforeCommit(const WriteRequest& request) {
  if (std::chrono::system_clock::now() > request.deadline) {
    throw StorageError(StorageError::Code::kDeadlineExceeded,
                       "the call's deadline passed before its write was committed; nothing "
                       "was written (retry with the same request id)");
  }
}

}  // namespace forestmap::storage
