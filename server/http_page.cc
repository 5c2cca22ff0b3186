#include "server/http_page.h"

// Eigen (through convert.h) before httplib.h: httplib pulls in <resolv.h>, whose `_res` macro
// breaks Eigen's headers when they come after it.
#include "server/convert.h"
// clang-format off
#include <httplib.h>
// clang-format on

#include <nlohmann/json.hpp>
#include <stdexcept>

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

void AddRoutes(httplib::Server& http, storage::MapStore& store, const RecentAnswers& answers) {
  http.Get("/", [](const httplib::Request&, httplib::Response& response) {
    response.set_content(kHttpPageHtml, "text/html; charset=utf-8");
  });
  http.Get("/api/maps", [&store](const httplib::Request&, httplib::Response& response) {
    Guarded(response, [&] {
      Json maps = Json::array();
      for (const storage::MapInfo& info : store.ListMaps()) maps.push_back(MapJson(info));
      Reply(response, maps);
    });
  });
  http.Get(R"(/api/maps/([A-Za-z0-9_.\-]+)/trees)",
           [&store](const httplib::Request& request, httplib::Response& response) {
             Guarded(response, [&] {
               const storage::MapSnapshot snapshot = store.ReadMap(request.matches[1]);
               Json trees = Json::array();
               for (const storage::TreeRecord& t : snapshot.trees) {
                 trees.push_back({t.x, t.y, t.dbh ? Json(*t.dbh) : Json(nullptr),
                                  t.status == storage::TreeStatus::kConfirmed});
               }
               Reply(response, Json{{"map", MapJson(snapshot.info)}, {"trees", trees}});
             });
           });
  http.Get(R"(/api/maps/([A-Za-z0-9_.\-]+)/versions)",
           [&store](const httplib::Request& request, httplib::Response& response) {
             Guarded(response, [&] {
               Json versions = Json::array();
               for (const storage::VersionRecord& v : store.ListVersions(request.matches[1], 0)) {
                 const v1::MapVersion version = ToProto(v);
                 versions.push_back({{"version", version.version()},
                                     {"kind", v1::MapVersion::Kind_Name(version.kind())},
                                     {"source", version.source()},
                                     {"trees", version.tree_count()},
                                     {"time_ms", version.created_unix_ms()}});
               }
               Reply(response, versions);
             });
           });
  http.Get("/api/relocalizations",
           [&answers](const httplib::Request&, httplib::Response& response) {
             Json list = Json::array();
             for (const RecentAnswer& a : answers.Get()) {
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
             Reply(response, list);
           });
}

}  // namespace

HttpPage::HttpPage(storage::MapStore& store, const RecentAnswers& answers,
                   const std::string& address)
    : http_(std::make_unique<httplib::Server>()) {
  AddRoutes(*http_, store, answers);
  const size_t colon = address.rfind(':');
  if (colon == std::string::npos) {
    throw std::runtime_error("--http " + address + ": give host:port");
  }
  const std::string host = address.substr(0, colon);
  int port = std::stoi(address.substr(colon + 1));
  if (port == 0) {
    port = http_->bind_to_any_port(host);
  } else if (!http_->bind_to_port(host, port)) {
    port = -1;
  }
  if (port < 0) throw std::runtime_error("--http " + address + ": cannot bind");
  address_ = host + ":" + std::to_string(port);
  thread_ = std::thread([this] { http_->listen_after_bind(); });
}

HttpPage::~HttpPage() {
  http_->stop();
  if (thread_.joinable()) thread_.join();
}

}  // namespace forestmap::server
