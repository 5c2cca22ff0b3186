#pragma once
// Structured error details (AIP-193), shared by client and server: a status carries, beside its
// message, a google.rpc.Status in its details (gRPC's trailer grpc-status-details-bin) whose
// `details` hold a google.rpc.BadRequest, one field violation per bad field: `field` is the path
// ("trees[12].position.x"), `description` what is wrong with it.

#include <grpcpp/support/status.h>

#include <string>
#include <vector>

namespace forestmap {

struct FieldViolation {
  std::string field;        // path of the field in the request, e.g. "trees[12].position.x"
  std::string description;  // what is wrong, for a person
};

// `code` and `message` as given, with a google.rpc.BadRequest holding `violations` in the
// details. Without violations: a plain status.
grpc::Status StatusWithBadRequest(grpc::StatusCode code, const std::string& message,
                                  const std::vector<FieldViolation>& violations);

// The field violations of every google.rpc.BadRequest in `status`'s details; empty when it has
// none, or details that do not parse (never throws).
std::vector<FieldViolation> BadRequestViolations(const grpc::Status& status);

}  // namespace forestmap
