#include "server/status.h"

#include <cstdio>
#include <exception>
#include <mutex>
#include <new>

#include "server/logging.h"
#include "storage/map_store.h"

namespace forestmap::server {
namespace {

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
    case Code::kInternal:
      break;
  }
  return grpc::StatusCode::INTERNAL;
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
  } catch (const ServiceError& e) {
    return grpc::Status(e.code(), e.what());
  } catch (const storage::StorageError& e) {
    if (e.code() == storage::StorageError::Code::kInternal) return InternalFault(rpc, e.what());
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

void LogLine(std::string_view line) noexcept { Log(LogLevel::kInfo, line); }

void LogStatus(std::string_view rpc, const grpc::Status& status) noexcept {
  if (status.ok()) return;
  try {
    // Debug only: the RPC's own log line (server/rpc_observer.h) carries code and message.
    Log(LogLevel::kDebug, "status",
        {{"rpc", std::string(rpc)},
         {"code", StatusCodeName(status.error_code())},
         {"error", status.error_message()}});
  } catch (...) {
    // Logging must never take the server down.
  }
}

}  // namespace forestmap::server
