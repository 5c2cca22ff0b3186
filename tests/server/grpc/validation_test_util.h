#pragma once
// Helpers shared by the tests of the gRPC layer's request checks: a NaN to put in fields, and the
// field a ValidationError names.

#include <limits>
#include <string>

#include "server/app/errors.h"

namespace forestmap::test {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The field a ValidationError of `body` names (google.rpc.BadRequest), or "" when none is thrown.
template <typename Body>
std::string BadField(Body&& body) {
  try {
    body();
  } catch (const server::ValidationError& e) {
    return e.field();
  }
  return "";
}

}  // namespace forestmap::test
