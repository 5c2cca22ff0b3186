#pragma once
// The one place where exceptions become grpc::Status. The exception types the server throws for
// outcomes whose status code is known where they are detected are the application layer's
// (server/app/errors.h).
//
// Mapping (see StatusFromCurrentException):
//   ServiceError (and subclasses)       -> the status of its ErrorCode, its message; a
//                                          ValidationError also with a google.rpc.BadRequest
//                                          naming its field (details)
//   storage::StorageError kNotFound      -> NOT_FOUND
//                         kAlreadyExists -> ALREADY_EXISTS
//                         kInvalidArgument -> INVALID_ARGUMENT
//                         kConflict      -> ABORTED (the client may retry)
//                         kDeadlineExceeded -> DEADLINE_EXCEEDED (nothing was committed)
//                         kInternal      -> INTERNAL "internal error; see server log" (logged)
//                         kFull          -> RESOURCE_EXHAUSTED "database full: ..." (logged)
//                         kReadOnly      -> FAILED_PRECONDITION "database read-only: ..." (logged)
//                         kCorrupt       -> DATA_LOSS "database corrupt: ..." (logged)
//                         kUnavailable   -> UNAVAILABLE "database unavailable: ... retry later"
//                         (the four faults: the client gets the cause, the log the details)
//   std::invalid_argument                -> INVALID_ARGUMENT
//   std::bad_alloc                       -> RESOURCE_EXHAUSTED "server out of memory" (logged)
//   anything else                        -> INTERNAL "internal error; see server log" (logged)
//   (no exception) work queue full       -> RESOURCE_EXHAUSTED "server busy ..." (ServerBusy)
//   (no handler) request bytes that do not parse -> INVALID_ARGUMENT (UndecodableRequest)
// Every non-OK status is logged (server/ops/logging.h); server faults with their real cause.

#include <grpcpp/support/status.h>

#include <string>
#include <string_view>
#include <utility>

#include "proto/status_code_name.h"
#include "server/app/errors.h"

namespace forestmap::server {

inline constexpr const char* kInternalErrorMessage = "internal error; see server log";

// Maps the exception currently being handled to a status and logs it. Call only inside a
// catch block. Never throws.
grpc::Status StatusFromCurrentException(std::string_view rpc) noexcept;

// RESOURCE_EXHAUSTED "server busy ..." for a call that found the work queue full (logged).
grpc::Status ServerBusy(std::string_view rpc) noexcept;

// INVALID_ARGUMENT for a request message of `method` ("/forestmap.v1.ForestMap/GetMap") that
// cannot be decoded (server/grpc/decode_guard.h); gRPC itself would answer UNIMPLEMENTED.
grpc::Status UndecodableRequest(std::string_view method) noexcept;

// Log lines through server/ops/logging.h (thread-safe, never throw): LogStatus at debug level (the
// RPC's own line reports its status), LogLine at info level.
void LogStatus(std::string_view rpc, const grpc::Status& status) noexcept;
void LogLine(std::string_view line) noexcept;

using forestmap::StatusCodeName;  // proto/status_code_name.h

// Runs `body` and returns OK, or the status of the exception it threw. No exception escapes.
template <typename Body>
grpc::Status RunGuarded(std::string_view rpc, Body&& body) noexcept {
  try {
    std::forward<Body>(body)();
    return grpc::Status::OK;
  } catch (...) {
    return StatusFromCurrentException(rpc);
  }
}

}  // namespace forestmap::server
