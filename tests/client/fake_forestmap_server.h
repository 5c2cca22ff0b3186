#pragma once
// An in-memory stand-in for forestmapd, for testing the client and the CLI without the real
// server. It keeps the API's documented behaviour (statuses, versions, id assignment, chunked
// streams) and records what it received. Relocalize answers from the request size: >= 10 trees
// LOCALIZED (at the prior position, heading 0, when given, else at kFakePose), 3..9 NOT_FOUND,
// < 3 INVALID_ARGUMENT. ListMaps answers pages of kListPage maps (tokens: the last name).

#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "forestmap/v1/forestmap_service.grpc.pb.h"
#include "proto/error_details.h"

namespace forestmap::client::testing {

struct FakeMap {
  v1::Map info;
  std::vector<v1::Tree> trees;
};

class FakeForestMapService final : public v1::ForestMap::Service {
 public:
  // Pose returned without a prior: x 10, y 20, z 1, yaw 30 deg.
  static constexpr double kX = 10, kY = 20, kZ = 1, kYawDeg = 30;
  static constexpr int kExportChunk = 1000;
  static constexpr int kListPage = 2;

  std::mutex mutex;
  std::map<std::string, FakeMap> maps;
  std::vector<v1::UploadTreesRequest> upload_messages;  // of the last upload
  v1::RelocalizeRequest last_relocalize;
  bool fail_uploads = false;  // answer every upload with INTERNAL

  grpc::Status CreateMap(grpc::ServerContext*, const v1::CreateMapRequest* request,
                         v1::Map* response) override {
    std::lock_guard lock(mutex);
    if (request->name().empty()) {  // with error details, as forestmapd's checks answer
      return StatusWithBadRequest(grpc::StatusCode::INVALID_ARGUMENT, "name is empty",
                                  {{"name", "name is empty"}});
    }
    if (maps.count(request->name())) {
      return {grpc::StatusCode::ALREADY_EXISTS, "map '" + request->name() + "' exists"};
    }
    FakeMap& map = maps[request->name()];
    map.info.set_name(request->name());
    map.info.set_description(request->description());
    map.info.set_crs(request->crs());
    map.info.set_version(1);
    map.info.set_created_unix_ms(1700000000000);
    map.info.set_updated_unix_ms(1700000000000);
    *response = map.info;
    return grpc::Status::OK;
  }

  grpc::Status ListMaps(grpc::ServerContext*, const v1::ListMapsRequest* request,
                        v1::ListMapsResponse* response) override {
    std::lock_guard lock(mutex);
    for (auto it = maps.upper_bound(request->page_token()); it != maps.end(); ++it) {
      if (response->maps_size() == kListPage) {
        response->set_next_page_token(response->maps(kListPage - 1).name());
        break;
      }
      *response->add_maps() = it->second.info;
    }
    return grpc::Status::OK;
  }

  grpc::Status GetMap(grpc::ServerContext*, const v1::GetMapRequest* request,
                      v1::Map* response) override {
    std::lock_guard lock(mutex);
    const auto it = maps.find(request->name());
    if (it == maps.end()) return NotFound(request->name());
    *response = it->second.info;
    return grpc::Status::OK;
  }

  grpc::Status DeleteMap(grpc::ServerContext*, const v1::DeleteMapRequest* request,
                         v1::DeleteMapResponse*) override {
    std::lock_guard lock(mutex);
    if (maps.erase(request->name()) == 0) return NotFound(request->name());
    return grpc::Status::OK;
  }

  grpc::Status UploadTrees(grpc::ServerContext*, grpc::ServerReader<v1::UploadTreesRequest>* reader,
                           v1::UploadTreesResponse* response) override {
    std::vector<v1::UploadTreesRequest> messages;
    v1::UploadTreesRequest message;
    while (reader->Read(&message)) messages.push_back(message);
    std::lock_guard lock(mutex);
    upload_messages = messages;
    if (fail_uploads) return {grpc::StatusCode::INTERNAL, "disk full"};
    if (messages.empty() || !messages[0].has_header()) {
      return {grpc::StatusCode::INVALID_ARGUMENT, "header is missing"};
    }
    const v1::UploadTreesHeader& header = messages[0].header();
    if (header.create_map()) {  // created with its trees, as forestmapd does
      const std::string& name = header.name();
      if (maps.count(name)) return {grpc::StatusCode::ALREADY_EXISTS, "map '" + name + "' exists"};
      FakeMap& created = maps[name];
      created.info.set_name(name);
      created.info.set_description(header.description());
      created.info.set_crs(header.crs());
      created.info.set_version(1);
      created.info.set_created_unix_ms(1700000000000);
      created.info.set_updated_unix_ms(1700000000000);
    }
    const auto it = maps.find(header.name());
    if (it == maps.end()) return NotFound(header.name());
    FakeMap& map = it->second;
    if (header.replace()) map.trees.clear();
    int64_t next_id = 0;
    for (const v1::Tree& tree : map.trees) next_id = std::max(next_id, tree.id() + 1);
    for (const auto& m : messages) {
      for (const v1::Tree& tree : m.chunk().trees()) {
        if (tree.has_id()) next_id = std::max(next_id, tree.id() + 1);
      }
    }
    for (const auto& m : messages) {
      for (v1::Tree tree : m.chunk().trees()) {
        if (!tree.has_id()) tree.set_id(next_id++);
        map.trees.push_back(tree);
        response->set_trees_received(response->trees_received() + 1);
      }
    }
    std::sort(map.trees.begin(), map.trees.end(),
              [](const v1::Tree& a, const v1::Tree& b) { return a.id() < b.id(); });
    UpdateInfo(map);
    *response->mutable_map() = map.info;
    return grpc::Status::OK;
  }

  grpc::Status ExportTrees(grpc::ServerContext*, const v1::ExportTreesRequest* request,
                           grpc::ServerWriter<v1::ExportTreesResponse>* writer) override {
    std::lock_guard lock(mutex);
    const auto it = maps.find(request->name());
    if (it == maps.end()) return NotFound(request->name());
    const FakeMap& map = it->second;
    v1::ExportTreesResponse chunk;
    chunk.set_map_version(map.info.version());
    for (const v1::Tree& tree : map.trees) {
      if (request->has_box() &&
          (tree.x() < request->box().min_x() || tree.x() > request->box().max_x() ||
           tree.y() < request->box().min_y() || tree.y() > request->box().max_y())) {
        continue;
      }
      *chunk.add_trees() = tree;
      if (chunk.trees_size() == kExportChunk) {
        writer->Write(chunk);
        chunk.clear_trees();
      }
    }
    if (chunk.trees_size() > 0 || map.trees.empty()) writer->Write(chunk);
    return grpc::Status::OK;
  }

  grpc::Status Relocalize(grpc::ServerContext*, const v1::RelocalizeRequest* request,
                          v1::RelocalizeResponse* response) override {
    std::lock_guard lock(mutex);
    last_relocalize = *request;
    // A set of maps answers in its last name, or in the first map for a pattern or every map.
    std::string name = request->name();
    if (request->has_maps()) {
      const v1::MapSet& set = request->maps();
      name = set.names_size() > 0 ? set.names(set.names_size() - 1)
                                  : (maps.empty() ? "" : maps.begin()->first);
    }
    if (!maps.count(name)) return NotFound(name);
    response->set_map_name(name);
    if (request->trees_size() < 3) {  // as forestmapd: an answer, not an error
      response->set_status(v1::RelocalizeResponse::STATUS_NOT_FOUND);
      response->set_reason(v1::RelocalizeResponse::REASON_TOO_FEW_TREES);
      response->set_detail("need at least 3 query trees");
      return grpc::Status::OK;
    }
    response->set_server_time_ms(2.5);
    response->set_map_version(maps[name].info.version());
    if (request->trees_size() < 10) {
      response->set_status(v1::RelocalizeResponse::STATUS_NOT_FOUND);
      response->set_detail("too few trees matched");
      response->set_inliers(2);
      return grpc::Status::OK;
    }
    response->set_status(v1::RelocalizeResponse::STATUS_LOCALIZED);
    if (request->has_prior()) {
      response->mutable_map_from_sensor()->mutable_translation()->set_x(request->prior().x());
      response->mutable_map_from_sensor()->mutable_translation()->set_y(request->prior().y());
      response->mutable_map_from_sensor()->mutable_rotation()->set_w(1);
    } else {
      const double half_yaw = kYawDeg * M_PI / 360.0;
      v1::Pose* pose = response->mutable_map_from_sensor();
      pose->mutable_translation()->set_x(kX);
      pose->mutable_translation()->set_y(kY);
      pose->mutable_translation()->set_z(kZ);
      pose->mutable_rotation()->set_z(std::sin(half_yaw));
      pose->mutable_rotation()->set_w(std::cos(half_yaw));
    }
    response->set_inliers(request->trees_size());
    response->set_rmse_m(0.125);
    response->set_confidence(0.75);
    return grpc::Status::OK;
  }

 private:
  static grpc::Status NotFound(const std::string& name) {
    return {grpc::StatusCode::NOT_FOUND, "no map named '" + name + "'"};
  }

  static void UpdateInfo(FakeMap& map) {
    map.info.set_version(map.info.version() + 1);
    map.info.set_tree_count(static_cast<int64_t>(map.trees.size()));
    map.info.clear_extent();
    for (size_t i = 0; i < map.trees.size(); ++i) {
      const v1::Tree& t = map.trees[i];
      v1::Box2* box = map.info.mutable_extent();
      box->set_min_x(i == 0 ? t.x() : std::min(box->min_x(), t.x()));
      box->set_min_y(i == 0 ? t.y() : std::min(box->min_y(), t.y()));
      box->set_max_x(i == 0 ? t.x() : std::max(box->max_x(), t.x()));
      box->set_max_y(i == 0 ? t.y() : std::max(box->max_y(), t.y()));
    }
  }
};

// The fake service listening on a free local port.
class FakeForestMapServer {
 public:
  FakeForestMapServer() {
    grpc::ServerBuilder builder;
    builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port_);
    builder.RegisterService(&service_);
    server_ = builder.BuildAndStart();
  }
  ~FakeForestMapServer() { server_->Shutdown(); }

  std::string address() const { return "127.0.0.1:" + std::to_string(port_); }
  FakeForestMapService& service() { return service_; }

 private:
  FakeForestMapService service_;
  int port_ = 0;
  std::unique_ptr<grpc::Server> server_;
};

}  // namespace forestmap::client::testing
