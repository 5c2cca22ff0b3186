#pragma once
// ListMaps and ListVersions, a page at a time (AIP-158).
//
// page_size 0 asks for kDefaultPageSize items, more than kMaxPageSize gets kMaxPageSize, a
// negative one is INVALID_ARGUMENT. A page_token is web-safe base64 of the listing's arguments
// (so that it only continues the listing it came from) and its position: opaque to clients, and
// no secret (it holds nothing the caller does not know; every page re-checks the caller's
// rights). A token that is not one, or belongs to another listing, is INVALID_ARGUMENT naming
// page_token. next_page_token is empty on the last page (never an empty page after a full one).
//   ListMaps      by name (bytewise); a page continues after the last name of the previous one,
//                 so maps created or deleted meanwhile show or vanish, none repeats.
//   ListVersions  oldest first; the pages list the versions readable when the first page was
//                 asked for (its newest `limit` ones when limit > 0), minus those pruned since.

#include "forestmap/v1/maps.pb.h"
#include "forestmap/v1/observations.pb.h"
#include "server/ops/auth.h"
#include "storage/map_store.h"

namespace forestmap::server {

inline constexpr int kDefaultPageSize = 100;  // items of a page when page_size is 0
inline constexpr int kMaxPageSize = 1000;     // items of a page at most

// The maps `caller` may read. Throws ValidationError (page_size, page_token).
v1::ListMapsResponse ListMapsPage(storage::MapStore& store, const Caller& caller,
                                  const v1::ListMapsRequest& request);

// A map's history. Throws ValidationError (name, limit, page_size, page_token) and the store's
// errors (kNotFound for the map).
v1::ListVersionsResponse ListVersionsPage(storage::MapStore& store,
                                          const v1::ListVersionsRequest& request);

}  // namespace forestmap::server
