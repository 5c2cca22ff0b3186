#pragma once
// forestmapd --http ADDR: a read-only web page (cpp-httplib) showing the maps, their versions,
// a map's trees with pan and zoom, and the last relocalizations. Nothing on it writes.
//
// Tokens as server/http/page_auth.h says: once the server has a token, every route needs a valid
// one with read access; /api/maps and /api/relocalizations list only the maps it can read. A
// browser's first visit to /?token=<secret> moves the token into the cookie `forestmap_token`
// (HttpOnly, SameSite=Strict) and reloads the page without it in its address.
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
  // Binds `address` ("host:port", port 0: any) and serves on its own thread until destroyed.
  // Throws std::runtime_error when the address cannot be bound. `store`, `answers` and `tokens`
  // (the server's token store; null: open) must outlive the page.
  HttpPage(storage::MapStore& store, const RecentAnswers& answers, const std::string& address,
           storage::TokenStore* tokens = nullptr);

  const std::string& address() const { return listener_.address(); }  // host:port bound

 private:
  HttpListener listener_;
};

// The page itself (http_page_html.cc).
extern const char* const kHttpPageHtml;

}  // namespace forestmap::server
