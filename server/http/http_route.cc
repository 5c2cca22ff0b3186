#include "server/http/http_route.h"

#include <algorithm>

#include "server/http/httplib_include.h"

namespace forestmap::server {
namespace {

constexpr std::string_view kMapsPrefix = "/api/maps/";

bool IsNameChar(char c) {
  return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' ||
         c == '.' || c == '-';
}

}  // namespace

PageRoute RoutePage(std::string_view path, std::string* map) {
  if (path == "/") return PageRoute::kPage;
  if (path == "/api/maps") return PageRoute::kMaps;
  if (path == "/api/relocalizations") return PageRoute::kRelocalizations;
  if (!path.starts_with(kMapsPrefix)) return PageRoute::kNotFound;
  const std::string_view rest = path.substr(kMapsPrefix.size());
  const size_t slash = rest.find('/');
  if (slash == 0 || slash == std::string_view::npos) return PageRoute::kNotFound;
  const std::string_view name = rest.substr(0, slash);
  if (!std::all_of(name.begin(), name.end(), IsNameChar)) return PageRoute::kNotFound;
  const std::string_view what = rest.substr(slash);
  const PageRoute route = what == "/trees"      ? PageRoute::kTrees
                          : what == "/density"  ? PageRoute::kDensity
                          : what == "/versions" ? PageRoute::kVersions
                          : what == "/boundary" ? PageRoute::kBoundary
                                                : PageRoute::kNotFound;
  if (route != PageRoute::kNotFound && map != nullptr) *map = std::string(name);
  return route;
}

std::string CookieValue(std::string_view cookies, std::string_view name) {
  for (size_t at = 0; at < cookies.size();) {
    const size_t end = std::min(cookies.find(';', at), cookies.size());
    std::string_view pair = cookies.substr(at, end - at);
    while (!pair.empty() && pair.front() == ' ') pair.remove_prefix(1);
    if (pair.starts_with(name) && pair.substr(name.size()).starts_with('=')) {
      return std::string(pair.substr(name.size() + 1));
    }
    at = end + 1;
  }
  return "";
}

PageRequest ReadPageRequest(const httplib::Request& request) {
  PageRequest read;
  read.route = RoutePage(request.path, &read.map);
  read.has_token_param = request.has_param("token");
  read.authorization = request.get_header_value("Authorization");
  if (!read.authorization.empty()) return read;
  if (read.has_token_param && read.route == PageRoute::kPage) {
    read.token = request.get_param_value("token");
  }
  read.token_in_query = !read.token.empty();
  if (read.token.empty())
    read.token = CookieValue(request.get_header_value("Cookie"), kTokenCookie);
  return read;
}

}  // namespace forestmap::server
