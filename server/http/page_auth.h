#pragma once
// Who asks the web port (the page and OGC API - Features, server/http/http_page.h): once the
// server has a token, every route needs a valid one with read access, read from the request as
// server/http/http_route.h says (Authorization: Bearer, else the page's cookie; ?token= only on
// the page itself, whose first visit moves it into the cookie). ?token= on any other route ->
// 400, tokens or not; none, unknown, revoked or expired -> 401; a map the token may not read ->
// 403.

#include <optional>
#include <string>
#include <string_view>

#include "server/http/http_route.h"
#include "storage/token_store.h"

namespace httplib {
struct Response;
}  // namespace httplib

namespace forestmap::server {

// `open` without tokens, else the caller's valid token.
struct PageCaller {
  bool open = true;
  std::optional<storage::TokenRecord> token;
  bool CanRead(std::string_view map) const {
    return open || (token && token->Allows(storage::Role::kRead, map));
  }
};

// The caller of `request`, or nullopt after answering 401 (tokens in force, no valid token).
// `tokens` null: open.
std::optional<PageCaller> Authenticate(storage::TokenStore* tokens, const PageRequest& request,
                                       httplib::Response& response);

// Answers 403 unless `caller` may read map `map`.
bool MayRead(const PageCaller& caller, const std::string& map, httplib::Response& response);

}  // namespace forestmap::server
