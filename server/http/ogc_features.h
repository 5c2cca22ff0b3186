#pragma once
// OGC API - Features (OGC 17-069r4, Part 1: Core and GeoJSON; Part 2: Coordinate Reference
// Systems by Reference) on the web port, read-only, under /ogc: GIS clients (QGIS, GDAL's OAPIF
// driver) open a server's maps as live layers. Each map is a collection, each tree of its current
// version a point feature: {tree_id, dbh_m, status, observations, and the survey's attributes}.
//
// Routes: GET /ogc                                 landing page
//         GET /ogc/api                             the API definition (OpenAPI 3.0)
//         GET /ogc/conformance                     the conformance classes above
//         GET /ogc/collections                     the maps the caller may read
//         GET /ogc/collections/NAME                one map: extent, CRSs
//         GET /ogc/collections/NAME/items          trees: limit, bbox, bbox-crs, crs (paged)
//         GET /ogc/collections/NAME/items/ID       one tree
//         GET /ogc/collections/NAME:boundary[/items[/1]]  the map's survey boundary, when it has
//                                                  one (server/http/ogc_boundary.h)
// CRSs: a map with a CRS answers in WGS 84 longitude, latitude (OGC CRS84, the default) or, when
// its CRS has an EPSG code, in that CRS (its storage CRS); bbox-crs takes the same. A map without a
// CRS answers in its own coordinates and names no CRS. Paging: at most `limit` trees by increasing
// id (default 1000, at most 10,000), and a `next` link that continues after the last one within
// the same map version, so a client pages a map of any size through bounded memory and sees one
// consistent version. Unknown parameters and malformed values answer 400 with the reason.
// Tokens as for the page (server/http/page_auth.h): a map the token may not read is absent from
// /ogc/collections and answers 403.

#include <string>

#include "storage/map_store.h"
#include "storage/token_store.h"

namespace httplib {
class Server;
}  // namespace httplib

namespace forestmap::server {

inline constexpr int kOgcDefaultLimit = 1'000;
inline constexpr int kOgcMaxLimit = 10'000;

// Adds the routes above to `http`; links are absolute, "SCHEME://<Host header>/ogc/...".
// `store` and `tokens` (null: open) must outlive `http`.
void AddOgcFeatureRoutes(httplib::Server& http, storage::MapStore& store,
                         storage::TokenStore* tokens, const std::string& scheme);

}  // namespace forestmap::server
