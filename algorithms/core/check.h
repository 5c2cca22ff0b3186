#pragma once

#include <sstream>
#include <stdexcept>
#include <string>

namespace forestmap::algorithms {

// Throws std::invalid_argument("what (got value)") unless `ok`: the one check behind every
// options struct's Check() and every precondition on caller input.
inline void Require(bool ok, const std::string& what, double value) {
  if (ok) return;
  std::ostringstream message;
  message << what << " (got " << value << ")";
  throw std::invalid_argument(message.str());
}

// Throws std::invalid_argument(what) unless `ok`.
inline void Require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument(what);
}

}  // namespace forestmap::algorithms
