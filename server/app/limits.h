#pragma once
// Sizes the application layer relies on, which every transport checks the same way.

namespace forestmap::server {

// Trees a relocalization query needs at least (three make the smallest constellation).
inline constexpr int kMinQueryTrees = 3;
// Maps one relocalization question may search by default (RelocalizeRequest.maps): each is a
// full search, and each holds its index in memory while the question runs.
inline constexpr int kDefaultMaxQueryMaps = 16;

}  // namespace forestmap::server
