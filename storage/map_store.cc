#include "storage/map_store.h"

#include <cmath>
#include <string>

namespace forestmap::storage {

// The schema's migration to version 3 computes the same floor in SQL (storage/sqlite/schema.cc).
ObservationCell CellOf(double x, double y) {
  return {static_cast<int64_t>(std::floor(x / kObservationCellSize)),
          static_cast<int64_t>(std::floor(y / kObservationCellSize))};
}

std::string ValidateMapName(const std::string& name) {
  constexpr size_t kMaxLength = 128;
  if (name.empty()) return "a map name must not be empty";
  if (name.size() > kMaxLength) {
    return "a map name must be at most 128 characters long (got " + std::to_string(name.size()) +
           ")";
  }
  for (size_t i = 0; i < name.size(); ++i) {
    const char c = name[i];
    const bool allowed = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') ||
                         (c >= '0' && c <= '9') || c == '_' || c == '.' || c == '-';
    if (!allowed) {
      return "a map name may only contain the characters A-Z a-z 0-9 _ . - (character " +
             std::to_string(i + 1) + " is not one of them)";
    }
  }
  if (name == "." || name == "..") {
    return "a map name must not be \".\" or \"..\" (a URL path resolves them: the web page's "
           "/api/maps/NAME/trees would name another path)";
  }
  return "";
}

}  // namespace forestmap::storage
