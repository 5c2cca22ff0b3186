#pragma once
// forestmapd --http ADDR: a read-only web page (cpp-httplib) showing the maps, their versions,
// a map's trees with pan and zoom, and the last relocalizations. Nothing on it writes.
//
// Tokens: once the server has a token (storage/token_store.h, deny by default as for
// the RPCs), every route needs a valid one with read access, sent as `Authorization: Bearer
// <secret>` (the scheme in any case), or by a browser as the cookie `forestmap_token`, which the
// page sets on a first visit to /?token=<secret> before it reloads itself without the token in
// its address (HttpOnly, SameSite=Strict, and Secure over HTTPS); ?token= is also read on any
// route (before the cookie). None, unknown, revoked or expired -> 401, a map the token may not
// read -> 403; /api/maps and /api/relocalizations list only the maps the token can read. How a
// request is read and routed: server/http/http_route.h.
//
// With an HttpsSetup (forestmapd's --tls-cert: the gRPC port's certificate and client
// verification) the page is HTTPS only.
//
// Routes: GET /                        the page (server/http/http_page_html.cc)
//         GET /api/maps                [{name, trees, version, crs, extent}]
//         GET /api/maps/NAME/trees     {trees: [[x, y, dbh|null, confirmed, id], ...]} (current;
//                                      ?bbox=MIN_X,MIN_Y,MAX_X,MAX_Y: those inside)
//         GET /api/maps/NAME/density   trees per cell of a 256-cell grid (server/http/http_trees.h)
//         GET /api/maps/NAME/versions  [{version, kind, source, trees, time_ms}]
//         GET /api/relocalizations     the last answers, newest first
//         GET /ogc/...                 OGC API - Features (server/http/ogc_features.h)

#include <string>

#include "server/app/recent_answers.h"
#include "server/http/http_listen.h"
#include "storage/map_store.h"
#include "storage/token_store.h"

namespace forestmap::server {

class HttpPage {
 public:
  // Binds `address` ("host:port", port 0: any) and serves on its own thread until destroyed
  // (HTTPS with `https`). Throws std::runtime_error when the address cannot be bound. `store`,
  // `answers` and `tokens` (the server's token store; null: open) must outlive the page.
  HttpPage(storage::MapStore& store, const RecentAnswers& answers, const std::string& address,
           storage::TokenStore* tokens = nullptr, const HttpsSetup& https = {});

  const std::string& address() const { return listener_.address(); }  // host:port bound
  std::string url() const { return listener_.url(); }                 // http(s)://host:port

 private:
  HttpListener listener_;
};

// The page itself (http_page_html.cc).
extern const char* const kHttpPageHtml;

}  // namespace forestmap::server
