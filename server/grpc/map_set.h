#pragma once
// Relocalize over a set of maps (RelocalizeRequest.maps, relocalization.proto): the set checked,
// resolved to the maps the caller may read, narrowed to those that may hold the sensor
// (server/app/map_set_relocalize.h), and the question's answer in the API's terms.

#include <string>
#include <string_view>
#include <vector>

#include "algorithms/relocalization/relocalizer.h"
#include "forestmap/v1/relocalization.pb.h"
#include "server/app/map_set_relocalize.h"
#include "server/ops/auth.h"
#include "storage/map_store.h"

namespace forestmap::server {

// The maps the set names that `caller` may read, with their MapInfo: listed names must exist
// (storage kNotFound) and allow `rpc` (ServiceError kPermissionDenied); a pattern or
// all_readable takes the readable maps of the store (none: ServiceError kNotFound). Then
// CandidateMaps narrows them for `query`; more than `max_maps` left, or more than `max_searches`
// searches (SearchCount): LimitError.
std::vector<storage::MapInfo> ResolveMapSet(storage::MapStore& store, const Caller& caller,
                                            std::string_view rpc, const v1::MapSet& set,
                                            const algorithms::RelocalizeQuery& query,
                                            const algorithms::RelocalizerOptions& options,
                                            int max_maps, int max_searches);

// The question's answer: the result (ToProto), and of the reported map its name, version; the
// rival map's name when two maps disagree; each match's map when not the reported one. (No time,
// stamp or geodetic pose: the caller adds them.)
v1::RelocalizeResponse ToProto(const MapSetAnswer& answer);

}  // namespace forestmap::server
