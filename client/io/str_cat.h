#pragma once
// String concatenation by appending. Why: GCC 12 raises a false -Wrestrict error (GCC bug
// 105651) on `"literal" + std::to_string(...)` once inlined, and warnings are errors here.

#include <initializer_list>
#include <string>
#include <string_view>

namespace forestmap::client {

inline std::string StrCat(std::initializer_list<std::string_view> parts) {
  size_t size = 0;
  for (std::string_view part : parts) size += part.size();
  std::string out;
  out.reserve(size);
  for (std::string_view part : parts) out.append(part);
  return out;
}

}  // namespace forestmap::client
