#include "storage/write_request.h"

namespace forestmap::storage {
namespace {

thread_local const WriteRequest* current_request = nullptr;

}  // namespace

WriteRequestScope::WriteRequestScope(const WriteRequest& request) : previous_(current_request) {
  current_request = &request;
}

WriteRequestScope::~WriteRequestScope() { current_request = previous_; }

const WriteRequest* CurrentWriteRequest() { return current_request; }

}  // namespace forestmap::storage
