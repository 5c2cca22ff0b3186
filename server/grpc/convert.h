#pragma once
// Conversions between the API messages (forestmap::v1) and the storage / algorithm types (rows
// as the algorithms see them: server/app/tree_records.h). Pure functions; they assume validated
// input (server/grpc/validation.h) and never throw on it.
//
// Conventions:
// - Optional proto scalars <-> std::optional in storage, NaN ("unknown") in algorithms.
// - An absent DetectedTree.axis becomes a zero vector (algorithms: "unknown axis").
// - Quaternions are normalised on the way in; an absent rotation is the identity and an absent
//   translation is zero.

#include <string>

#include "algorithms/core/geometry.h"
#include "algorithms/merging/map_merge.h"
#include "algorithms/relocalization/relocalizer.h"
#include "algorithms/relocalization/tracking.h"
#include "forestmap/v1/maps.pb.h"
#include "forestmap/v1/observations.pb.h"
#include "forestmap/v1/relocalization.pb.h"
#include "forestmap/v1/tracking.pb.h"
#include "proto/geometry_convert.h"
#include "server/app/shared_map.h"
#include "storage/map_store.h"

namespace forestmap::server {

// Maps and trees. A tree's shared-map fields (status, observations, sigmas) go out but are not
// read back: uploaded trees are surveys, confirmed by definition.
v1::Map ToProto(const storage::MapInfo& info);
v1::Tree ToProto(const storage::TreeRecord& tree);
storage::TreeRecord FromProto(const v1::Tree& tree);
v1::Box2 ToProto(const storage::Extent& extent);
storage::Extent FromProto(const v1::Box2& box);
// A survey boundary (map frame, m) both ways; the store checks it (storage/boundary_json.h).
v1::SurveyBoundary ToProto(const storage::Boundary& boundary);
storage::Boundary FromProto(const v1::SurveyBoundary& boundary);

// Geometry.
using forestmap::FromProto;  // Vector3 and Pose: proto/geometry_convert.h
using forestmap::ToProto;

// Relocalization.
algorithms::DetectedTree FromProto(const v1::DetectedTree& tree);
// A prior at (x, y), or from the deprecated pose of release 0.1.0 (only its x, y are used).
algorithms::PriorPose FromProto(const v1::PriorPose& prior);
algorithms::RelocalizeQuery FromProto(const v1::RelocalizeRequest& request);
v1::RelocalizeResponse::Status ToProto(algorithms::RelocalizeStatus status);
v1::RelocalizeResponse::Reason ToProto(algorithms::RelocalizeReason reason);
// Everything but server_time_ms and map_version, which the service fills in.
v1::RelocalizeResponse ToProto(const algorithms::RelocalizeResult& result);

// Tracking. The response lacks frame_id, server_time_ms and map_version (the stream fills them).
algorithms::TrackingFrame FromProto(const v1::TrackFrame& frame);
v1::TrackResponse ToProto(const algorithms::TrackingStep& step);

// Shared maps.
v1::MapVersion ToProto(const storage::VersionRecord& record);
v1::MapVersion::Kind ToProto(storage::VersionKind kind);
// An Observe request as the application layer takes it: frames without a pose are relocalized
// first, base_version counts only with REJECT_IF_STALE. `write` is left to the caller (request
// id and deadline of the call).
ObserveCall FromProto(const v1::ObserveRequest& request);
// The answer to an Observe, without server_time_ms (the service fills it in).
v1::ObserveResponse ToProto(const ObserveOutcome& outcome);

}  // namespace forestmap::server
