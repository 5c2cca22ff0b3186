#include "server/http/page_auth.h"

// clang-format off
#include "server/http/httplib_include.h"
// clang-format on

#include <nlohmann/json.hpp>

namespace forestmap::server {

using Json = nlohmann::json;

std::optional<PageCaller> Authenticate(storage::TokenStore* tokens, const PageRequest& request,
                                       httplib::Response& response) {
  PageCaller caller;
  if (request.has_token_param && request.route != PageRoute::kPage) {
    // Addresses end up in logs, proxies and browser histories: only the page's first visit
    // takes a token there (and moves it into a cookie at once).
    response.status = 400;
    response.set_content(
        Json{{"error",
              "a token in the address (?token=) is refused here: send 'Authorization: Bearer "
              "<token>', or in a browser open the page once as /?token=<token> (it keeps the "
              "token in a cookie)"}}
            .dump(),
        "application/json");
    return std::nullopt;
  }
  if (tokens == nullptr || !tokens->AnyToken()) return caller;
  caller.open = false;
  const std::string secret = request.authorization.empty()
                                 ? request.token
                                 : std::string(storage::BearerSecret(request.authorization));
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
