#pragma once
// Sizes the application layer relies on, which every transport checks the same way.

namespace forestmap::server {

// Trees a relocalization query needs at least (three make the smallest constellation).
inline constexpr int kMinQueryTrees = 3;
// Maps one relocalization question may name or find by default (RelocalizeRequest.maps), and
// the searches it may run: maps of one CRS are searched at once in the index of their union
// (map_union.h), a map without CRS alone; each search holds its index while the question runs.
inline constexpr int kDefaultMaxQueryMaps = 1000;
inline constexpr int kDefaultMaxQuerySearches = 16;

}  // namespace forestmap::server
