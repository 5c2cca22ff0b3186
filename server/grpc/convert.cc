#include "server/grpc/convert.h"

#include <cmath>
#include <optional>

#include "server/grpc/geo_convert.h"
#include "server/grpc/legacy_layout.h"

namespace forestmap::server {
namespace {

// The unit vector of `v`, scaled by its largest component first, so that vectors of any finite
// length (1e308 long, whose norm overflows, or 1e-300, whose squares underflow) keep their
// direction. Zero for a zero or non-finite vector (validation refuses those where it matters).
Eigen::Vector3d Direction(const Eigen::Vector3d& v) {
  const double largest = v.cwiseAbs().maxCoeff();
  if (!(largest > 0) || !std::isfinite(largest)) return Eigen::Vector3d::Zero();
  return (v / largest).normalized();
}

}  // namespace

v1::Map ToProto(const storage::MapInfo& info) {
  v1::Map map;
  map.set_name(info.name);
  map.set_description(info.description);
  map.set_crs(info.crs);
  map.set_version(info.version);
  map.set_tree_count(info.tree_count);
  if (info.extent) *map.mutable_extent() = ToProto(*info.extent);
  map.set_created_unix_ms(info.created_unix_ms);
  map.set_updated_unix_ms(info.updated_unix_ms);
  map.set_has_boundary(info.has_boundary);
  DescribeCrs(map);
  return map;
}

v1::Tree ToProto(const storage::TreeRecord& tree) {
  v1::Tree out;
  if (tree.id) out.set_id(*tree.id);
  out.set_x(tree.x);
  out.set_y(tree.y);
  if (tree.z) out.set_z(*tree.z);
  if (tree.dbh) out.set_dbh(*tree.dbh);
  out.mutable_attributes()->insert(tree.attributes.begin(), tree.attributes.end());
  for (const std::string& name : tree.null_attributes) out.add_null_attributes(name);
  out.set_status(tree.status == storage::TreeStatus::kConfirmed ? v1::TREE_STATUS_CONFIRMED
                                                                : v1::TREE_STATUS_CANDIDATE);
  out.set_observations(tree.observations);
  if (tree.position_sigma) out.set_position_sigma_m(*tree.position_sigma);
  if (tree.dbh_sigma) out.set_dbh_sigma_m(*tree.dbh_sigma);
  if (tree.last_seen_unix_ms) out.set_last_seen_unix_ms(*tree.last_seen_unix_ms);
  return out;
}

storage::TreeRecord FromProto(const v1::Tree& tree) {
  storage::TreeRecord out;
  if (tree.has_id()) out.id = tree.id();
  out.x = tree.x();
  out.y = tree.y();
  if (tree.has_z()) out.z = tree.z();
  if (tree.has_dbh()) out.dbh = tree.dbh();
  out.attributes.insert(tree.attributes().begin(), tree.attributes().end());
  out.null_attributes.insert(tree.null_attributes().begin(), tree.null_attributes().end());
  return out;
}

v1::Box2 ToProto(const storage::Extent& extent) {
  v1::Box2 box;
  box.set_min_x(extent.min_x);
  box.set_min_y(extent.min_y);
  box.set_max_x(extent.max_x);
  box.set_max_y(extent.max_y);
  return box;
}

storage::Extent FromProto(const v1::Box2& box) {
  return storage::Extent{box.min_x(), box.min_y(), box.max_x(), box.max_y()};
}

v1::SurveyBoundary ToProto(const storage::Boundary& boundary) {
  const auto fill = [](const storage::BoundaryRing& ring, v1::Ring& out) {
    out.mutable_vertices()->Reserve(static_cast<int>(ring.size()));
    for (const storage::BoundaryPoint& p : ring) {
      v1::Vector2* vertex = out.add_vertices();
      vertex->set_x(p.x);
      vertex->set_y(p.y);
    }
  };
  v1::SurveyBoundary out;
  for (const storage::BoundaryPolygon& polygon : boundary) {
    v1::Polygon* added = out.add_polygons();
    fill(polygon.outer, *added->mutable_outer());
    for (const storage::BoundaryRing& hole : polygon.holes) fill(hole, *added->add_holes());
  }
  return out;
}

storage::Boundary FromProto(const v1::SurveyBoundary& boundary) {
  const auto ring_of = [](const v1::Ring& ring) {
    storage::BoundaryRing points;
    points.reserve(static_cast<size_t>(ring.vertices_size()));
    for (const v1::Vector2& p : ring.vertices()) points.push_back({p.x(), p.y()});
    return points;
  };
  storage::Boundary out;
  out.reserve(static_cast<size_t>(boundary.polygons_size()));
  for (const v1::Polygon& polygon : boundary.polygons()) {
    storage::BoundaryPolygon& added = out.emplace_back();
    added.outer = ring_of(polygon.outer());
    for (const v1::Ring& hole : polygon.holes()) added.holes.push_back(ring_of(hole));
  }
  return out;
}

algorithms::DetectedTree FromProto(const v1::DetectedTree& tree) {
  algorithms::DetectedTree out;
  out.position = FromProto(tree.position());
  out.dbh = tree.has_dbh() ? tree.dbh() : algorithms::kUnknown;
  out.axis = tree.has_axis() ? Direction(FromProto(tree.axis())) : Eigen::Vector3d::Zero();
  out.score = tree.has_score() ? tree.score() : algorithms::kUnknown;
  return out;
}

algorithms::PriorPose FromProto(const v1::PriorPose& prior) {
  algorithms::PriorPose out;  // the relocalizer uses the position's x and y only
  if (const v1::Pose* pose = LegacyPose(prior)) {
    out.map_from_sensor = FromProto(*pose);
  } else {
    out.map_from_sensor.translation() = Eigen::Vector3d(prior.x(), prior.y(), 0.0);
  }
  out.radius = prior.radius_m();
  return out;
}

algorithms::RelocalizeQuery FromProto(const v1::RelocalizeRequest& request) {
  algorithms::RelocalizeQuery query;
  query.trees.reserve(request.trees_size());
  for (const v1::DetectedTree& tree : request.trees()) query.trees.push_back(FromProto(tree));
  if (request.has_gravity()) query.gravity = Direction(FromProto(request.gravity()));
  if (request.has_prior()) query.prior = FromProto(request.prior());
  return query;
}

v1::RelocalizeResponse::Status ToProto(algorithms::RelocalizeStatus status) {
  switch (status) {
    case algorithms::RelocalizeStatus::kLocalized:
      return v1::RelocalizeResponse::STATUS_LOCALIZED;
    case algorithms::RelocalizeStatus::kAmbiguous:
      return v1::RelocalizeResponse::STATUS_AMBIGUOUS;
    case algorithms::RelocalizeStatus::kNotFound:
      return v1::RelocalizeResponse::STATUS_NOT_FOUND;
  }
  return v1::RelocalizeResponse::STATUS_UNSPECIFIED;
}

v1::RelocalizeResponse::Reason ToProto(algorithms::RelocalizeReason reason) {
  using R = algorithms::RelocalizeReason;
  switch (reason) {
    case R::kNone:
      return v1::RelocalizeResponse::REASON_NONE;
    case R::kTooFewTrees:
      return v1::RelocalizeResponse::REASON_TOO_FEW_TREES;
    case R::kNoMatchingConstellation:
      return v1::RelocalizeResponse::REASON_NO_MATCHING_CONSTELLATION;
    case R::kNotSignificant:
      return v1::RelocalizeResponse::REASON_NOT_SIGNIFICANT;
    case R::kTooFewInliers:
      return v1::RelocalizeResponse::REASON_TOO_FEW_INLIERS;
    case R::kAmbiguous:
      return v1::RelocalizeResponse::REASON_AMBIGUOUS_RIVAL;
    case R::kOutsidePrior:
      return v1::RelocalizeResponse::REASON_OUTSIDE_PRIOR;
    case R::kOutsideCoverage:
      return v1::RelocalizeResponse::REASON_OUTSIDE_COVERAGE;
  }
  return v1::RelocalizeResponse::REASON_UNSPECIFIED;
}

v1::RelocalizeResponse ToProto(const algorithms::RelocalizeResult& result) {
  v1::RelocalizeResponse out;
  out.set_status(ToProto(result.status));
  if (result.status == algorithms::RelocalizeStatus::kLocalized) {
    *out.mutable_map_from_sensor() = ToProto(result.map_from_sensor);
  }
  out.set_inliers(result.inliers);
  out.mutable_matches()->Reserve(static_cast<int>(result.matches.size()));
  for (const algorithms::TreeMatch& match : result.matches) {
    v1::TreeMatch* m = out.add_matches();
    m->set_query_index(match.query_index);
    m->set_map_tree_id(match.map_tree_id);
    m->set_distance_m(match.distance);
  }
  out.set_rmse_m(result.rmse);
  out.set_confidence(result.confidence);
  out.set_detail(result.detail);
  out.set_reason(ToProto(result.reason));
  out.set_coverage_share(result.coverage_share);
  out.set_trees_in_coverage(result.trees_in_coverage);
  if (result.status == algorithms::RelocalizeStatus::kAmbiguous && result.rival_map_from_sensor) {
    *out.mutable_rival_map_from_sensor() = ToProto(*result.rival_map_from_sensor);
  }
  if (result.status == algorithms::RelocalizeStatus::kLocalized) {
    out.mutable_covariance()->Reserve(36);
    for (int r = 0; r < 6; ++r) {
      for (int c = 0; c < 6; ++c) out.add_covariance(result.covariance(r, c));
    }
  }
  return out;
}

algorithms::TrackingFrame FromProto(const v1::TrackFrame& message) {
  algorithms::TrackingFrame frame;
  frame.query.trees.reserve(message.trees_size());
  for (const v1::DetectedTree& tree : message.trees()) frame.query.trees.push_back(FromProto(tree));
  if (message.has_gravity()) frame.query.gravity = Direction(FromProto(message.gravity()));
  if (message.has_odometry()) frame.odometry = FromProto(message.odometry());
  return frame;
}

v1::TrackResponse ToProto(const algorithms::TrackingStep& step) {
  v1::TrackResponse out;
  switch (step.state) {
    case algorithms::TrackState::kTracking:
      out.set_state(v1::TrackResponse::STATE_TRACKING);
      break;
    case algorithms::TrackState::kRecovered:
      out.set_state(v1::TrackResponse::STATE_RECOVERED);
      break;
    case algorithms::TrackState::kLost:
      out.set_state(v1::TrackResponse::STATE_LOST);
      break;
  }
  switch (step.method) {
    case algorithms::TrackMethod::kLocal:
      out.set_method(v1::TrackResponse::METHOD_LOCAL);
      break;
    case algorithms::TrackMethod::kPrior:
      out.set_method(v1::TrackResponse::METHOD_PRIOR);
      break;
    case algorithms::TrackMethod::kGlobal:
      out.set_method(v1::TrackResponse::METHOD_GLOBAL);
      break;
  }
  out.set_frames_lost(step.frames_lost);
  *out.mutable_result() = ToProto(step.result);
  return out;
}

v1::MapVersion::Kind ToProto(storage::VersionKind kind) {
  using Kind = storage::VersionKind;
  switch (kind) {
    case Kind::kCreate:
      return v1::MapVersion::KIND_CREATE;
    case Kind::kUpload:
      return v1::MapVersion::KIND_UPLOAD;
    case Kind::kReplace:
      return v1::MapVersion::KIND_REPLACE;
    case Kind::kObserve:
      return v1::MapVersion::KIND_OBSERVE;
    case Kind::kRestore:
      return v1::MapVersion::KIND_RESTORE;
    case Kind::kRemoveSource:
      return v1::MapVersion::KIND_REMOVE_SOURCE;
    case Kind::kMigrated:
      return v1::MapVersion::KIND_MIGRATED;
  }
  return v1::MapVersion::KIND_UNSPECIFIED;
}

v1::MapVersion ToProto(const storage::VersionRecord& record) {
  v1::MapVersion out;
  out.set_version(record.version);
  out.set_created_unix_ms(record.created_unix_ms);
  out.set_kind(ToProto(record.kind));
  out.set_source(record.source);
  out.set_tree_count(record.tree_count);
  out.set_confirmed_count(record.confirmed_count);
  out.set_trees_added(record.trees_added);
  out.set_trees_updated(record.trees_updated);
  out.set_trees_removed(record.trees_removed);
  out.set_observations_added(record.observations_added);
  out.set_observations_removed(record.observations_removed);
  out.set_restored_from(record.restored_from);
  return out;
}

ObserveCall FromProto(const v1::ObserveRequest& request) {
  ObserveCall call;
  call.map_name = request.name();
  call.source = request.source();
  if (request.conflict_policy() == v1::CONFLICT_POLICY_REJECT_IF_STALE)
    call.base_version = request.base_version();
  call.frames.reserve(request.frames_size());
  for (const v1::ObservationFrame& in : request.frames()) {
    ObserveFrame& frame = call.frames.emplace_back();
    frame.observations.source = request.source();
    frame.observations.frame_id = in.frame_id();
    frame.observations.trees.reserve(in.trees_size());
    for (const v1::DetectedTree& tree : in.trees())
      frame.observations.trees.push_back(FromProto(tree));
    frame.has_pose = in.has_map_from_sensor();
    if (frame.has_pose) frame.observations.map_from_sensor = FromProto(in.map_from_sensor());
    if (in.has_gravity()) frame.gravity = Direction(FromProto(in.gravity()));
    frame.pose_sigma = {in.position_sigma(), in.yaw_sigma()};
  }
  call.sensor_range = request.sensor_range();
  call.detection_probability = request.detection_probability();
  call.merge_only = request.merge_only();
  return call;
}

v1::ObserveResponse ToProto(const ObserveOutcome& outcome) {
  v1::ObserveResponse out;
  for (const FrameOutcome& frame : outcome.frames) {
    v1::FrameResult& result = *out.add_frames();
    result.set_frame_id(frame.frame_id);
    if (!frame.merged) {
      result.set_status(v1::FrameResult::STATUS_SKIPPED);
      result.set_detail(frame.detail);
      continue;
    }
    result.set_status(v1::FrameResult::STATUS_MERGED);
    result.set_relocalized(frame.relocalized);
    *result.mutable_map_from_sensor() = ToProto(frame.map_from_sensor);
    result.set_trees_associated(frame.counts.associated);
    result.set_trees_added(frame.counts.added);
    result.set_trees_promoted(frame.counts.promoted);
    result.set_trees_ignored(frame.counts.ignored);
    result.set_trees_missed(frame.counts.missed);
    result.set_trees_removed(frame.counts.removed);
  }
  out.set_map_version(outcome.map.version);
  *out.mutable_map() = ToProto(outcome.map);
  return out;
}

}  // namespace forestmap::server
