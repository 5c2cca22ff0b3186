#pragma once
// A map's survey boundary on OGC API - Features (server/http/ogc_features.h): a second collection
// per map that has one, "NAME:boundary" (':' is in no map name, so the id is never a map's),
// holding one feature: the boundary as a MultiPolygon (id 1; properties map, version, polygons).
// The map's collection links to it (rel "related"), it links back (rel "collection" of its
// items). Same CRSs and parameters as the map's trees (crs, bbox, bbox-crs, limit, f).

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "storage/map_store.h"

namespace httplib {
struct Request;
struct Response;
}  // namespace httplib

namespace forestmap::server::ogc {

inline constexpr const char* kBoundarySuffix = ":boundary";

// "NAME:boundary".
std::string BoundaryCollectionId(const std::string& map);

// The collection of the boundary of map `info` (which has one: `boundary` not empty).
nlohmann::json BoundaryCollectionJson(const storage::MapInfo& info,
                                      const storage::Boundary& boundary, const std::string& base);

// Answers .../NAME:boundary/items (`feature` unset) or .../items/ID: the boundary's feature in the
// CRS asked for, none when bbox misses it; 404 for an ID other than 1. BadParameter (400) for a
// malformed parameter.
void ReplyBoundaryItems(const httplib::Request& request, httplib::Response& response,
                        const storage::MapInfo& info, const storage::Boundary& boundary,
                        const std::string& base, std::optional<int64_t> feature);

}  // namespace forestmap::server::ogc
