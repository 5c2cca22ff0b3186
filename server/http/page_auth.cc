#include "server/http/page_auth.h"

// clang-format off
#include <httplib.h>
// clang-format on

#include <algorithm>
#include <nlohmann/json.hpp>

namespace forestmap::server {
namespace {

using Json = nlohmann::json;

// The token `request` carries: its Authorization header ("Bearer <token>"), else its cookie
// (set by the page, below), else ?token= (a browser's first visit).
std::string RequestToken(const httplib::Request& request) {
  const std::string header = request.get_header_value("Authorization");
  if (!header.empty()) return std::string(storage::BearerSecret(header));
  // Cookie: name=value; name2=value2
  const std::string cookies = request.get_header_value("Cookie");
  for (size_t at = 0; at < cookies.size();) {
    const size_t end = std::min(cookies.find(';', at), cookies.size());
    std::string_view pair = std::string_view(cookies).substr(at, end - at);
    while (!pair.empty() && pair.front() == ' ') pair.remove_prefix(1);
    if (pair.starts_with(kTokenCookie) && pair.substr(kTokenCookie.size()).starts_with('=')) {
      return std::string(pair.substr(kTokenCookie.size() + 1));
    }
    at = end + 1;
  }
  return request.get_param_value("token");
}

}  // namespace

std::optional<PageCaller> Authenticate(storage::TokenStore* tokens, const httplib::Request& request,
                                       httplib::Response& response) {
  PageCaller caller;
  if (tokens == nullptr || !tokens->AnyToken()) return caller;
  caller.open = false;
  const std::string secret = RequestToken(request);
  if (!secret.empty()) caller.token = tokens->Find(secret);
  if (caller.token) return caller;
  response.status = 401;
  response.set_header("WWW-Authenticate", "Bearer");
  response.set_content(Json{{"error", secret.empty() ? "this server requires a token: send "
                                                       "'Authorization: Bearer <token>' or open "
                                                       "the page as /?token=<token>"
                                                     : "unknown, revoked or expired token"}}
                           .dump(),
                       "application/json");
  return std::nullopt;
}

bool MayRead(const PageCaller& caller, const std::string& map, httplib::Response& response) {
  if (caller.CanRead(map)) return true;
  response.status = 403;
  response.set_content(Json{{"error", "token " + std::to_string(caller.token->id) +
                                          " may not read map '" + map + "'"}}
                           .dump(),
                       "application/json");
  return false;
}

}  // namespace forestmap::server
