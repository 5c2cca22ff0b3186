#pragma once
// The wire layouts of release 0.1.0 that the server still reads, so that older clients keep
// working: their fields are deprecated in the protos and read only here (the rest of the server
// sees the current layout).
//   UploadTreesRequest  name, replace, trees, request_id, create_map, description, crs on the
//                       message itself (now UploadTreesHeader, then TreeChunk messages)
//   TrackRequest        name, trees, gravity, odometry, frame_id, client_stamp_ns on the message
//                       itself (now TrackHeader, then TrackFrame messages)
//   PruneVersionsRequest  request_id in field 3 (now field 50, as in every request)
//   PriorPose           a full map_from_sensor pose (now x, y: all the server ever used of it)

#include <google/protobuf/repeated_ptr_field.h>

#include <cstdint>
#include <optional>
#include <string>

#include "forestmap/v1/maps.pb.h"
#include "forestmap/v1/observations.pb.h"
#include "forestmap/v1/relocalization.pb.h"
#include "forestmap/v1/tracking.pb.h"

namespace forestmap::server {

// The error of a message that mixes the 0.1.0 layout with a header, chunk or frame.
inline constexpr const char* kMixedLayouts =
    ": a message holds either the fields of release 0.1.0 (name, trees, ...) or a header / "
    "chunk / frame, not both";

// True when the message sets any field of the 0.1.0 layout.
bool HasLegacyFields(const v1::UploadTreesRequest& message);
bool HasLegacyFields(const v1::TrackRequest& message);

// The header fields a 0.1.0 upload message carries (set on its first message; later ones may
// repeat name and request_id).
v1::UploadTreesHeader LegacyHeader(const v1::UploadTreesRequest& message);
// Its trees, moved out of the message.
google::protobuf::RepeatedPtrField<v1::Tree> TakeLegacyTrees(v1::UploadTreesRequest& message);

// The map a 0.1.0 Track message names ("" on later messages), and its frame (moved out).
v1::TrackHeader LegacyHeader(const v1::TrackRequest& message);
v1::TrackFrame TakeLegacyFrame(v1::TrackRequest& message);
// Of a Track message in either layout: the map it names ("" when none), and the id of the frame
// it holds (none for a header).
std::string FirstMessageMap(const v1::TrackRequest& message);
std::optional<int64_t> FrameIdOf(const v1::TrackRequest& message);

// PruneVersions' request id: request_id, or else the 0.1.0 field. Throws ValidationError when
// both are set and differ.
std::string RequestId(const v1::PruneVersionsRequest& request);

// The 0.1.0 prior pose, when the prior has one.
const v1::Pose* LegacyPose(const v1::PriorPose& prior);

}  // namespace forestmap::server
