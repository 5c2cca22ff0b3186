#include "server/grpc/legacy_layout.h"

#include "server/grpc/status.h"

// This file is where the deprecated fields are read; nowhere else.
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"

namespace forestmap::server {

bool HasLegacyFields(const v1::UploadTreesRequest& message) {
  return !message.name().empty() || message.replace() || message.trees_size() > 0 ||
         !message.request_id().empty() || message.create_map() || !message.description().empty() ||
         !message.crs().empty();
}

bool HasLegacyFields(const v1::TrackRequest& message) {
  return !message.name().empty() || message.trees_size() > 0 || message.has_gravity() ||
         message.has_odometry() || message.frame_id() != 0 || message.has_client_stamp_ns();
}

v1::UploadTreesHeader LegacyHeader(const v1::UploadTreesRequest& message) {
  v1::UploadTreesHeader header;
  header.set_name(message.name());
  header.set_replace(message.replace());
  header.set_request_id(message.request_id());
  header.set_create_map(message.create_map());
  header.set_description(message.description());
  header.set_crs(message.crs());
  return header;
}

google::protobuf::RepeatedPtrField<v1::Tree> TakeLegacyTrees(v1::UploadTreesRequest& message) {
  google::protobuf::RepeatedPtrField<v1::Tree> trees;
  trees.Swap(message.mutable_trees());
  return trees;
}

v1::TrackHeader LegacyHeader(const v1::TrackRequest& message) {
  v1::TrackHeader header;
  header.set_name(message.name());
  return header;
}

v1::TrackFrame TakeLegacyFrame(v1::TrackRequest& message) {
  v1::TrackFrame frame;
  frame.mutable_trees()->Swap(message.mutable_trees());
  if (message.has_gravity()) *frame.mutable_gravity() = message.gravity();
  if (message.has_odometry()) *frame.mutable_odometry() = message.odometry();
  frame.set_frame_id(message.frame_id());
  if (message.has_client_stamp_ns()) frame.set_client_stamp_ns(message.client_stamp_ns());
  return frame;
}

std::string FirstMessageMap(const v1::TrackRequest& message) {
  return message.has_header() ? message.header().name() : message.name();
}

std::optional<int64_t> FrameIdOf(const v1::TrackRequest& message) {
  if (message.has_header()) return std::nullopt;
  return message.has_frame() ? message.frame().frame_id() : message.frame_id();
}

std::string RequestId(const v1::PruneVersionsRequest& request) {
  const std::string& legacy = request.deprecated_request_id();
  if (request.request_id().empty()) return legacy;
  if (!legacy.empty() && legacy != request.request_id()) {
    throw ValidationError("deprecated_request_id",
                          " (field 3, the request_id of release 0.1.0) differs from request_id; "
                          "set request_id only");
  }
  return request.request_id();
}

const v1::Pose* LegacyPose(const v1::PriorPose& prior) {
  return prior.has_map_from_sensor() ? &prior.map_from_sensor() : nullptr;
}

}  // namespace forestmap::server
