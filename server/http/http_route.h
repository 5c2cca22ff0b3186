#pragma once
// How the web page (http_page.h) reads a request before it answers it: the route a path asks
// for, and the token the request carries. Pure functions of cpp-httplib's parsed request, so that
// tests/fuzz/fuzz_http_routes.cc drives them from raw request bytes (through cpp-httplib's own
// parsing) without a socket, a store or a token database.

#include <string>
#include <string_view>

namespace httplib {
struct Request;
}  // namespace httplib

namespace forestmap::server {

// The routes of the page (GET; cpp-httplib answers HEAD through them too).
enum class PageRoute {
  kPage,             // /
  kMaps,             // /api/maps
  kTrees,            // /api/maps/NAME/trees
  kDensity,          // /api/maps/NAME/density
  kVersions,         // /api/maps/NAME/versions
  kBoundary,         // /api/maps/NAME/boundary
  kRelocalizations,  // /api/relocalizations
  kNotFound,         // anything else: 404
};

// The cookie the page keeps a browser's token in.
inline constexpr std::string_view kTokenCookie = "forestmap_token";

struct PageRequest {
  PageRoute route = PageRoute::kNotFound;
  std::string map;  // of kTrees, kDensity, kVersions and kBoundary: one or more of [A-Za-z0-9_.-]
  std::string authorization;  // the Authorization header as sent ("Bearer <token>"), if any
  // Without an Authorization header: on the page itself (kPage) ?token= (a browser's first
  // visit), else the cookie. No other route reads a token from the address.
  std::string token;
  bool token_in_query = false;   // `token` is the page's ?token=
  bool has_token_param = false;  // ?token= is in the address (the page removes it, others refuse)
};

// The route of a (decoded) path; `map` gets the map name of the routes of one map.
PageRoute RoutePage(std::string_view path, std::string* map);

// The value of cookie `name` in a Cookie header ("a=1; b=2"); empty when absent.
std::string CookieValue(std::string_view cookies, std::string_view name);

PageRequest ReadPageRequest(const httplib::Request& request);

}  // namespace forestmap::server
