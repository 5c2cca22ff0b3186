#pragma once
// Sizes the application layer relies on, which every transport checks the same way.

namespace forestmap::server {

// Trees a relocalization query needs at least (three make the smallest constellation).
inline constexpr int kMinQueryTrees = 3;

}  // namespace forestmap::server
