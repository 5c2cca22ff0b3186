#pragma once
// Conversions between the API messages (forestmap::v1) and the storage / algorithm types.
// Pure functions; they assume validated input (server/validation.h) and never throw on it.
//
// Conventions:
// - Optional proto scalars <-> std::optional in storage, NaN ("unknown") in algorithms.
// - An absent DetectedTree.axis becomes a zero vector (algorithms: "unknown axis").
// - Quaternions are normalised on the way in; an absent rotation is the identity and an absent
//   translation is zero.

#include <vector>

#include "algorithms/geometry.h"
#include "algorithms/relocalizer.h"
#include "forestmap/v1/maps.pb.h"
#include "forestmap/v1/relocalization.pb.h"
#include "proto/geometry_convert.h"
#include "storage/map_store.h"

namespace forestmap::server {

// Maps and trees.
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
v1::RelocalizeResponse ToProto(const algorithms::RelocalizeResult& result);

}  // namespace forestmap::server
