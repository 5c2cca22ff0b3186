#include "server/http/http_page.h"

// Eigen (through http_page.h) before httplib.h: httplib pulls in <resolv.h>, whose `_res` macro
// breaks Eigen's headers when they come after it.
#include "server/http/http_route.h"
#include "server/http/http_trees.h"
// clang-format off
#include <httplib.h>
// clang-format on

#include <algorithm>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string_view>
#include <vector>

namespace forestmap::server {
namespace {

using Json = nlohmann::json;

Json MapJson(const storage::MapInfo& info) {
  Json map = {{"name", info.name},
              {"trees", info.tree_count},
              {"version", info.version},
              {"crs", info.crs.size() <= 32 ? info.crs : "WKT"}};
  if (info.extent) {
    map["extent"] = {info.extent->min_x, info.extent->min_y, info.extent->max_x,
                     info.extent->max_y};
  }
  return map;
}

void Reply(httplib::Response& response, const Json& body) {
  response.set_content(body.dump(), "application/json");
}

// Who asks (see http_page.h): `open` without tokens, else the caller's valid token.
struct PageCaller {
  bool open = true;
  std::optional<storage::TokenRecord> token;
  bool CanRead(std::string_view map) const {
    return open || (token && token->Allows(storage::Role::kRead, map));
  }
};

// The caller of `request`, or nullopt after answering 401 (tokens in force, no valid token).
std::optional<PageCaller> Authenticate(storage::TokenStore* tokens, const PageRequest& request,
                                       httplib::Response& response) {
  PageCaller caller;
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

// Answers 403 unless `caller` may read map `map`.
bool MayRead(const PageCaller& caller, const std::string& map, httplib::Response& response) {
  if (caller.CanRead(map)) return true;
  response.status = 403;
  response.set_content(Json{{"error", "token " + std::to_string(caller.token->id) +
                                          " may not read map '" + map + "'"}}
                           .dump(),
                       "application/json");
  return false;
}

// Runs `body`, turning a store error (unknown map, ...) into a 404 with its message.
template <typename Body>
void Guarded(httplib::Response& response, Body body) {
  try {
    body();
  } catch (const std::exception& e) {
    response.status = 404;
    Reply(response, Json{{"error", e.what()}});
  }
}

// The page's names of a version's kind and of a relocalization's status: its own, so that the
// page reads the same whatever the gRPC API calls them.
const char* KindName(storage::VersionKind kind) {
  using Kind = storage::VersionKind;
  switch (kind) {
    case Kind::kCreate:
      return "CREATE";
    case Kind::kUpload:
      return "UPLOAD";
    case Kind::kReplace:
      return "REPLACE";
    case Kind::kObserve:
      return "OBSERVE";
    case Kind::kRestore:
      return "RESTORE";
    case Kind::kRemoveSource:
      return "REMOVE_SOURCE";
    case Kind::kMigrated:
      return "MIGRATED";
  }
  return "KIND_UNSPECIFIED";
}

const char* StatusName(algorithms::RelocalizeStatus status) {
  switch (status) {
    case algorithms::RelocalizeStatus::kLocalized:
      return "LOCALIZED";
    case algorithms::RelocalizeStatus::kAmbiguous:
      return "AMBIGUOUS";
    case algorithms::RelocalizeStatus::kNotFound:
      return "NOT_FOUND";
  }
  return "STATUS_UNSPECIFIED";
}

Json VersionsJson(const std::vector<storage::VersionRecord>& records) {
  Json versions = Json::array();
  for (const storage::VersionRecord& v : records) {
    versions.push_back({{"version", v.version},
                        {"kind", KindName(v.kind)},
                        {"source", v.source},
                        {"trees", v.tree_count},
                        {"time_ms", v.created_unix_ms}});
  }
  return versions;
}

Json AnswersJson(const RecentAnswers& answers, const PageCaller& caller) {
  Json list = Json::array();
  for (const RecentAnswer& a : answers.Get()) {
    if (!caller.CanRead(a.map_name)) continue;
    Json item = {{"map", a.map_name},
                 {"time_ms", a.unix_ms},
                 {"status", StatusName(a.status)},
                 {"inliers", a.inliers}};
    if (a.position) {
      item["x"] = a.position->x();
      item["y"] = a.position->y();
    }
    if (a.geodetic) {
      item["lat"] = a.geodetic->latitude_deg;
      item["lon"] = a.geodetic->longitude_deg;
    }
    list.push_back(item);
  }
  return list;
}

// Answers `request` (read by ReadPageRequest) for `caller`; `secure`: over HTTPS.
void Answer(storage::MapStore& store, const RecentAnswers& answers, const PageRequest& request,
            const PageCaller& caller, bool secure, httplib::Response& response) {
  switch (request.route) {
    case PageRoute::kPage:
      if (caller.token && request.has_token_param) {
        // A browser's first visit, /?token=...: the token moves into a cookie that scripts
        // cannot read and other sites cannot send, and the page reloads without it in its
        // address (and so in the history); the fragment (#map=...) stays. Only the token that
        // was checked becomes the cookie.
        if (request.token_in_query) {
          response.set_header("Set-Cookie", std::string(kTokenCookie) + "=" + request.token +
                                                "; Path=/; HttpOnly; SameSite=Strict" +
                                                (secure ? "; Secure" : ""));
        }
        response.set_redirect("/", 303);
        return;
      }
      response.set_content(kHttpPageHtml, "text/html; charset=utf-8");
      return;
    case PageRoute::kMaps:
      Guarded(response, [&] {
        Json maps = Json::array();
        for (const storage::MapInfo& info : store.ListMaps()) {
          if (caller.CanRead(info.name)) maps.push_back(MapJson(info));
        }
        Reply(response, maps);
      });
      return;
    case PageRoute::kTrees:
      if (!MayRead(caller, request.map, response)) return;
      Guarded(response, [&] {
        const storage::MapInfo info = store.GetMap(request.map);
        ReplyTreesStreamed(response, store, info, MapJson(info).dump());
      });
      return;
    case PageRoute::kVersions:
      if (!MayRead(caller, request.map, response)) return;
      Guarded(response, [&] { Reply(response, VersionsJson(store.ListVersions(request.map, 0))); });
      return;
    case PageRoute::kRelocalizations:
      Reply(response, AnswersJson(answers, caller));
      return;
    case PageRoute::kNotFound:
      break;
  }
  response.status = 404;
  Reply(response, Json{{"error", "no such page"}});
}

void AddPageRoutes(httplib::Server& http, storage::MapStore& store, const RecentAnswers& answers,
                   storage::TokenStore* tokens, bool secure) {
  // Every GET path to one handler: the route is RoutePage's (http_route.h). [\s\S]: any byte,
  // newlines of a decoded path included.
  http.Get(R"([\s\S]*)", [&store, &answers, tokens, secure](const httplib::Request& request,
                                                            httplib::Response& response) {
    const PageRequest read = ReadPageRequest(request);
    const std::optional<PageCaller> caller = Authenticate(tokens, read, response);
    if (caller) Answer(store, answers, read, *caller, secure, response);
  });
}

}  // namespace

HttpPage::HttpPage(storage::MapStore& store, const RecentAnswers& answers,
                   const std::string& address, storage::TokenStore* tokens, const HttpsSetup& https)
    : listener_("--http", address, https, [&](httplib::Server& http) {
        AddPageRoutes(http, store, answers, tokens, static_cast<bool>(https));
      }) {}

}  // namespace forestmap::server
