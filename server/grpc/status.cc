#include "server/grpc/status.h"

#include <cstdio>
#include <exception>
#include <mutex>
#include <new>

#include "proto/error_details.h"
#include "server/ops/logging.h"
#include "storage/map_store.h"

namespace forestmap::server {
namespace {

grpc::StatusCode CodeOf(ErrorCode code) {
  switch (code) {
    case ErrorCode::kInvalidArgument:
      return grpc::StatusCode::INVALID_ARGUMENT;
    case ErrorCode::kNotFound:
      return grpc::StatusCode::NOT_FOUND;
    case ErrorCode::kAlreadyExists:
      return grpc::StatusCode::ALREADY_EXISTS;
    case ErrorCode::kFailedPrecondition:
      return grpc::StatusCode::FAILED_PRECONDITION;
    case ErrorCode::kAborted:
      return grpc::StatusCode::ABORTED;
    case ErrorCode::kResourceExhausted:
      return grpc::StatusCode::RESOURCE_EXHAUSTED;
    case ErrorCode::kCancelled:
      return grpc::StatusCode::CANCELLED;
    case ErrorCode::kUnauthenticated:
      return grpc::StatusCode::UNAUTHENTICATED;
    case ErrorCode::kPermissionDenied:
      return grpc::StatusCode::PERMISSION_DENIED;
  }
  return grpc::StatusCode::INTERNAL;
}

grpc::StatusCode CodeOf(storage::StorageError::Code code) {
  using Code = storage::StorageError::Code;
  switch (code) {
    case Code::kNotFound:
      return grpc::StatusCode::NOT_FOUND;
    case Code::kAlreadyExists:
      return grpc::StatusCode::ALREADY_EXISTS;
    case Code::kInvalidArgument:
      return grpc::StatusCode::INVALID_ARGUMENT;
    case Code::kConflict:
      return grpc::StatusCode::ABORTED;
    case Code::kDeadlineExceeded:
      return grpc::StatusCode::DEADLINE_EXCEEDED;
    case Code::kFull:
      return grpc::StatusCode::RESOURCE_EXHAUSTED;
    case Code::kReadOnly:
      return grpc::StatusCode::FAILED_PRECONDITION;
    case Code::kCorrupt:
      return grpc::StatusCode::DATA_LOSS;
    case Code::kUnavailable:
      return grpc::StatusCode::UNAVAILABLE;
    case Code::kInternal:
      break;
  }
  return grpc::StatusCode::INTERNAL;
}

// What the client is told about a fault of the database (kFull .. kUnavailable): the cause, without
// the server's paths or SQL; the log gets the store's full message. Empty for other codes.
const char* FaultMessage(storage::StorageError::Code code) {
  using Code = storage::StorageError::Code;
  switch (code) {
    case Code::kFull:
      return "database full: the server's database has no room for this write (disk full, or its "
             "size limit --max-db-mb reached); nothing was written";
    case Code::kReadOnly:
      return "database read-only: the server cannot write to its database (read-only file, "
             "directory or file system, or the file was moved or deleted); nothing was written";
    case Code::kCorrupt:
      return "database corrupt: the server's database is damaged; see the server log";
    case Code::kUnavailable:
      return "database unavailable: it stayed locked by another writer, or its server could not "
             "be reached; nothing was written, retry later";
    default:
      return "";
  }
}

grpc::Status StorageFault(std::string_view rpc, const storage::StorageError& e) {
  const grpc::StatusCode code = CodeOf(e.code());
  Log(LogLevel::kError, "database fault",
      {{"rpc", std::string(rpc)}, {"code", StatusCodeName(code)}, {"error", e.what()}});
  return grpc::Status(code, FaultMessage(e.code()));
}

// A fault of the server: the client gets a generic message, the log gets the real one.
grpc::Status InternalFault(std::string_view rpc, std::string_view what) {
  Log(LogLevel::kError, "internal fault",
      {{"rpc", std::string(rpc)}, {"error", std::string(what)}});
  return grpc::Status(grpc::StatusCode::INTERNAL, kInternalErrorMessage);
}

grpc::Status Classify(std::string_view rpc) {
  try {
    throw;
  } catch (const ValidationError& e) {
    return StatusWithBadRequest(CodeOf(e.code()), e.what(), {{e.field(), e.what()}});
  } catch (const ServiceError& e) {
    return grpc::Status(CodeOf(e.code()), e.what());
  } catch (const storage::StorageError& e) {
    if (e.code() == storage::StorageError::Code::kInternal) return InternalFault(rpc, e.what());
    if (*FaultMessage(e.code()) != '\0') return StorageFault(rpc, e);
    return grpc::Status(CodeOf(e.code()), e.what());
  } catch (const std::invalid_argument& e) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, e.what());
  } catch (const std::bad_alloc&) {
    Log(LogLevel::kError, "out of memory", {{"rpc", std::string(rpc)}});
    return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED, "server out of memory");
  } catch (const std::exception& e) {
    return InternalFault(rpc, e.what());
  } catch (...) {
    return InternalFault(rpc, "unknown exception");
  }
}

}  // namespace

grpc::Status StatusFromCurrentException(std::string_view rpc) noexcept {
  try {
    grpc::Status status = Classify(rpc);
    LogStatus(rpc, status);
    return status;
  } catch (...) {
    // Building the status itself failed (out of memory): answer without allocating more.
    return grpc::Status(grpc::StatusCode::INTERNAL, kInternalErrorMessage);
  }
}

grpc::Status ServerBusy(std::string_view rpc) noexcept {
  grpc::Status busy(grpc::StatusCode::RESOURCE_EXHAUSTED,
                    "server busy: too many requests are waiting; retry later");
  LogStatus(rpc, busy);
  return busy;
}

grpc::Status UndecodableRequest(std::string_view method) noexcept {
  try {
    const size_t slash = method.rfind('/');
    const std::string rpc(slash == std::string_view::npos ? method : method.substr(slash + 1));
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                        "the " + rpc +
                            " request cannot be decoded (not a valid protobuf message of its "
                            "type, or a string that is not UTF-8); nothing was done");
  } catch (...) {
    return grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "request cannot be decoded");
  }
}

void LogLine(std::string_view line) noexcept { Log(LogLevel::kInfo, line); }

void LogStatus(std::string_view rpc, const grpc::Status& status) noexcept {
  if (status.ok()) return;
  try {
    // Debug only: the RPC's own log line (server/grpc/rpc_observer.h) carries code and message.
    Log(LogLevel::kDebug, "status",
        {{"rpc", std::string(rpc)},
         {"code", StatusCodeName(status.error_code())},
         {"error", status.error_message()}});
  } catch (...) {
    // Logging must never take the server down.
  }
}

}  // namespace forestmap::server
