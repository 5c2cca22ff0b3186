#pragma once
// The errors of the server's requests, named by what went wrong rather than by transport. The
// application layer (server/app) and the transports throw them where the outcome is known; each
// transport maps an ErrorCode to its own answer (gRPC: server/grpc/status.cc, the one place where
// exceptions become grpc::Status). Faults of the database are storage::StorageError.

#include <functional>
#include <stdexcept>
#include <string>
#include <string_view>

namespace forestmap::server {

// Each code is answered as the gRPC status of the same name.
enum class ErrorCode {
  kInvalidArgument,     // the request is invalid in itself
  kNotFound,            // what the request names does not exist
  kAlreadyExists,       // what the request creates exists
  kFailedPrecondition,  // a valid request that the map's current state cannot serve
  kAborted,             // a concurrent change got in the way; the client may retry
  kResourceExhausted,   // over a configured limit
  kCancelled,           // the client gave up
  kUnauthenticated,     // no valid token
  kPermissionDenied,    // a valid token without the role the request needs
};

// An error whose code is known where it is thrown.
class ServiceError : public std::runtime_error {
 public:
  ServiceError(ErrorCode code, const std::string& message)
      : std::runtime_error(message), code_(code) {}
  ErrorCode code() const { return code_; }

 private:
  ErrorCode code_;
};

// A request that is invalid in itself: kInvalidArgument, naming `field` (a transport may say so
// apart: gRPC attaches a google.rpc.BadRequest). The message is the field path followed by
// `problem`: ValidationError("trees[12].position.x", " is NaN") reads "trees[12].position.x is
// NaN".
class ValidationError : public ServiceError {
 public:
  ValidationError(const std::string& field, const std::string& problem)
      : ServiceError(ErrorCode::kInvalidArgument, field + problem), field_(field) {}
  const std::string& field() const { return field_; }

 private:
  std::string field_;
};

// A request over a configured size limit: kResourceExhausted.
class LimitError : public ServiceError {
 public:
  explicit LimitError(const std::string& message)
      : ServiceError(ErrorCode::kResourceExhausted, message) {}
};

// A valid request that the current state of a map cannot serve (e.g. relocalizing in a map
// without trees): kFailedPrecondition.
class PreconditionError : public ServiceError {
 public:
  explicit PreconditionError(const std::string& message)
      : ServiceError(ErrorCode::kFailedPrecondition, message) {}
};

// How the application layer reports a failure that no caller can be answered with (a retention
// after a committed write, a pool job that threw): the server that wires the layer logs it.
// Must not throw.
using FaultReport = std::function<void(std::string_view message)>;

}  // namespace forestmap::server
