#pragma once
// Conversions between the API messages (forestmap::v1) and the storage / algorithm types.
// Pure functions; they assume validated input (server/validation.h) and never throw on it.
//
// Conventions:
// - Optional proto scalars <-> std::optional in storage, NaN ("unknown") in algorithms.
// - An absent DetectedTree.axis becomes a zero vector (algorithms: "unknown axis").
// - Quaternions are normalised on the way in; an absent rotation is the identity and an absent
//   translation is zero.

#include <map>
#include <set>
#include <string>
#include <vector>

#include "algorithms/core/geometry.h"
#include "algorithms/merging/map_merge.h"
#include "algorithms/relocalization/relocalizer.h"
#include "algorithms/relocalization/tracking.h"
#include "forestmap/v1/maps.pb.h"
#include "forestmap/v1/observations.pb.h"
#include "forestmap/v1/relocalization.pb.h"
#include "forestmap/v1/tracking.pb.h"
#include "proto/geometry_convert.h"
#include "storage/map_store.h"

namespace forestmap::server {

// Maps and trees. A tree's shared-map fields (status, observations, sigmas) go out but are not
// read back: uploaded trees are surveys, confirmed by definition.
v1::Map ToProto(const storage::MapInfo& info);
v1::Tree ToProto(const storage::TreeRecord& tree);
storage::TreeRecord FromProto(const v1::Tree& tree);
v1::Box2 ToProto(const storage::Extent& extent);
storage::Extent FromProto(const v1::Box2& box);

// A stored tree as the relocalizer sees it: unknown z / dbh are NaN. Requires tree.id.
algorithms::MapTree ToMapTree(const storage::TreeRecord& tree);
std::vector<algorithms::MapTree> ToMapTrees(const std::vector<storage::TreeRecord>& trees);

// Geometry.
using forestmap::FromProto;  // Vector3 and Pose: proto/geometry_convert.h
using forestmap::ToProto;

// Relocalization.
algorithms::DetectedTree FromProto(const v1::DetectedTree& tree);
algorithms::PriorPose FromProto(const v1::PriorPose& prior);
algorithms::RelocalizeQuery FromProto(const v1::RelocalizeRequest& request);
v1::RelocalizeResponse::Status ToProto(algorithms::RelocalizeStatus status);
// Everything but server_time_ms and map_version, which the service fills in.
v1::RelocalizeResponse::Reason ToProto(algorithms::RelocalizeReason reason);
v1::RelocalizeResponse ToProto(const algorithms::RelocalizeResult& result);

// Tracking. The response lacks frame_id, server_time_ms and map_version (the stream fills them).
algorithms::TrackingFrame FromProto(const v1::TrackRequest& request);
v1::TrackResponse ToProto(const algorithms::TrackingStep& step);

// Shared maps.
v1::MapVersion ToProto(const storage::VersionRecord& record);
v1::MapVersion::Kind ToProto(storage::VersionKind kind);
// Observation rows: storage <-> algorithms (unknown z / dbh: nullopt <-> NaN).
algorithms::TreeObservation ToTreeObservation(const storage::ObservationRecord& record);
storage::ObservationRecord ToObservationRecord(const algorithms::TreeObservation& observation);
// A merged tree as a stored row; `attributes` and `null_attributes` are the survey columns it
// keeps.
storage::TreeRecord ToTreeRecord(const algorithms::TreeEstimate& tree,
                                 const std::map<std::string, std::string>& attributes,
                                 const std::set<std::string>& null_attributes = {});
// A request frame (without its pose, which the service decides) for the merge.
algorithms::FrameObservations FromProto(const v1::ObservationFrame& frame,
                                        const std::string& source);

}  // namespace forestmap::server
