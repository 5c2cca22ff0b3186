#include "server/http/http_page.h"

// Eigen (through convert.h) before httplib.h: httplib pulls in <resolv.h>, whose `_res` macro
// breaks Eigen's headers when they come after it.
#include "server/grpc/convert.h"
#include "server/http/http_listen.h"
#include "server/http/http_trees.h"
// clang-format off
#include <httplib.h>
// clang-format on

#include <chrono>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string_view>
#include <vector>

namespace forestmap::server {
namespace {

using Json = nlohmann::json;

constexpr auto kStopPoll = std::chrono::milliseconds(5);  // while waiting for the listen loop

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
std::optional<PageCaller> Authenticate(storage::TokenStore* tokens, const httplib::Request& request,
                                       httplib::Response& response) {
  PageCaller caller;
  if (tokens == nullptr || !tokens->AnyToken()) return caller;
  caller.open = false;
  std::string secret = request.get_param_value("token");
  const std::string header = request.get_header_value("Authorization");
  constexpr std::string_view kBearer = "Bearer ";
  if (std::string_view(header).starts_with(kBearer)) secret = header.substr(kBearer.size());
  if (!secret.empty()) caller.token = tokens->Find(secret);
  if (caller.token) return caller;
  response.status = 401;
  response.set_header("WWW-Authenticate", "Bearer");
  response.set_content(Json{{"error", secret.empty() ? "this server requires a token: send "
                                                       "'Authorization: Bearer <token>' or open "
                                                       "the page as /?token=<token>"
                                                     : "unknown or revoked token"}}
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

Json VersionsJson(const std::vector<storage::VersionRecord>& records) {
  Json versions = Json::array();
  for (const storage::VersionRecord& v : records) {
    const v1::MapVersion version = ToProto(v);
    versions.push_back({{"version", version.version()},
                        {"kind", v1::MapVersion::Kind_Name(version.kind())},
                        {"source", version.source()},
                        {"trees", version.tree_count()},
                        {"time_ms", version.created_unix_ms()}});
  }
  return versions;
}

Json AnswersJson(const RecentAnswers& answers, const PageCaller& caller) {
  Json list = Json::array();
  for (const RecentAnswer& a : answers.Get()) {
    if (!caller.CanRead(a.map_name)) continue;
    const v1::RelocalizeResponse& r = a.response;
    Json item = {{"map", a.map_name},
                 {"time_ms", a.unix_ms},
                 {"status", v1::RelocalizeResponse::Status_Name(r.status())},
                 {"inliers", r.inliers()}};
    if (r.has_map_from_sensor()) {
      item["x"] = r.map_from_sensor().translation().x();
      item["y"] = r.map_from_sensor().translation().y();
    }
    if (r.has_geodetic()) {
      item["lat"] = r.geodetic().latitude_deg();
      item["lon"] = r.geodetic().longitude_deg();
    }
    list.push_back(item);
  }
  return list;
}

void AddRoutes(httplib::Server& http, storage::MapStore& store, const RecentAnswers& answers,
               storage::TokenStore* tokens) {
  using httplib::Request;
  using httplib::Response;
  http.Get("/", [tokens](const Request& request, Response& response) {
    if (!Authenticate(tokens, request, response)) return;
    response.set_content(kHttpPageHtml, "text/html; charset=utf-8");
  });
  http.Get("/api/maps", [&store, tokens](const Request& request, Response& response) {
    const std::optional<PageCaller> caller = Authenticate(tokens, request, response);
    if (!caller) return;
    Guarded(response, [&] {
      Json maps = Json::array();
      for (const storage::MapInfo& info : store.ListMaps()) {
        if (caller->CanRead(info.name)) maps.push_back(MapJson(info));
      }
      Reply(response, maps);
    });
  });
  http.Get(R"(/api/maps/([A-Za-z0-9_.\-]+)/trees)",
           [&store, tokens](const Request& request, Response& response) {
             const std::optional<PageCaller> caller = Authenticate(tokens, request, response);
             if (!caller || !MayRead(*caller, request.matches[1], response)) return;
             Guarded(response, [&] {
               const storage::MapInfo info = store.GetMap(request.matches[1]);
               ReplyTreesStreamed(response, store, info, MapJson(info).dump());
             });
           });
  http.Get(R"(/api/maps/([A-Za-z0-9_.\-]+)/versions)",
           [&store, tokens](const Request& request, Response& response) {
             const std::optional<PageCaller> caller = Authenticate(tokens, request, response);
             if (!caller || !MayRead(*caller, request.matches[1], response)) return;
             Guarded(response, [&] {
               Reply(response, VersionsJson(store.ListVersions(request.matches[1], 0)));
             });
           });
  http.Get("/api/relocalizations", [&answers, tokens](const Request& request, Response& response) {
    const std::optional<PageCaller> caller = Authenticate(tokens, request, response);
    if (caller) Reply(response, AnswersJson(answers, *caller));
  });
}

}  // namespace

HttpPage::HttpPage(storage::MapStore& store, const RecentAnswers& answers,
                   const std::string& address, storage::TokenStore* tokens)
    : http_(std::make_unique<httplib::Server>()) {
  AddRoutes(*http_, store, answers, tokens);
  address_ = BoundHttpAddress(address, BindHttpListener(*http_, "--http", address));
  thread_ = std::thread([this] {
    http_->listen_after_bind();
    stopped_ = true;
  });
}

HttpPage::~HttpPage() {
  // stop() is a no-op until the listen loop runs: repeat it until the loop has ended.
  while (!stopped_) {
    http_->stop();
    std::this_thread::sleep_for(kStopPoll);
  }
  thread_.join();
}

}  // namespace forestmap::server
