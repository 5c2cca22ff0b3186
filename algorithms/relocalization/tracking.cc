#include "algorithms/relocalization/tracking.h"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace forestmap::algorithms {

void TrackingOptions::Check() const {
  relocalizer.Check();
  auto require = [](bool ok, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("TrackingOptions: ") + what);
  };
  require(max_correction > 0 && yaw_window >= 0, "max_correction > 0, yaw_window >= 0");
  require(local_max_rmse > 0 && local_min_matched >= 0 && local_min_matched <= 1,
          "local_max_rmse > 0, local_min_matched in [0, 1]");
  require(prior_radius > 0 && radius_growth >= 0, "prior_radius > 0, radius_growth >= 0");
  require(global_after >= 0, "global_after must be >= 0");
}

Tracker::Tracker(const TrackingOptions& options) : options_(options) { options_.Check(); }

std::optional<TrackingStep> Tracker::TryLocal(const MapIndex& index,
                                              const TrackingFrame& frame) const {
  TrackingStep step;
  step.method = TrackMethod::kLocal;
  step.result =
      RefineNear(index, frame.query, *predicted_, options_.yaw_window, options_.relocalizer);
  if (step.result.status != RelocalizeStatus::kLocalized) return std::nullopt;
  // A loose or partial local fix, or one far from the prediction, may be a neighbouring
  // constellation: let a search (which checks for distinct alternatives) decide instead.
  const double in_range = static_cast<double>(std::count_if(
      frame.query.trees.begin(), frame.query.trees.end(), [&](const DetectedTree& tree) {
        return tree.position.head<2>().norm() <= options_.relocalizer.max_query_range;
      }));
  const double moved =
      (step.result.map_from_sensor.translation() - predicted_->translation()).head<2>().norm();
  if (step.result.rmse > options_.local_max_rmse ||
      step.result.inliers < options_.local_min_matched * in_range ||
      moved > options_.max_correction) {
    return std::nullopt;
  }
  step.state = TrackState::kTracking;
  return step;
}

TrackingStep Tracker::Step(const MapIndex& index, const TrackingFrame& frame) {
  if (predicted_ && frame.odometry) {
    *predicted_ = *predicted_ * *frame.odometry;
  } else if (predicted_ && options_.constant_velocity && velocity_) {
    predicted_->translation() += *velocity_;
  }

  std::optional<TrackingStep> step;
  if (predicted_ && frames_lost_ == 0) step = TryLocal(index, frame);
  if (!step && predicted_ && frames_lost_ < options_.global_after) {
    RelocalizeQuery query = frame.query;
    query.prior =
        PriorPose{*predicted_, options_.prior_radius + options_.radius_growth * frames_lost_};
    step = TrackingStep{TrackState::kRecovered, TrackMethod::kPrior,
                        Relocalize(index, query, options_.relocalizer), 0};
    if (step->result.status != RelocalizeStatus::kLocalized) step.reset();
  }
  if (!step) {
    RelocalizeQuery query = frame.query;
    query.prior.reset();
    step = TrackingStep{TrackState::kRecovered, TrackMethod::kGlobal,
                        Relocalize(index, query, options_.relocalizer), 0};
  }

  if (step->result.status == RelocalizeStatus::kLocalized) {
    const Pose3& fix = step->result.map_from_sensor;
    // The motion is only meaningful between consecutive fixes.
    velocity_.reset();
    if (last_fix_ && frames_lost_ == 0) velocity_ = fix.translation() - last_fix_->translation();
    last_fix_ = fix;
    predicted_ = fix;
    frames_lost_ = 0;
  } else {
    step->state = TrackState::kLost;
    step->frames_lost = ++frames_lost_;
  }
  return *step;
}

const char* ToString(TrackState state) {
  switch (state) {
    case TrackState::kTracking:
      return "tracking";
    case TrackState::kRecovered:
      return "recovered";
    case TrackState::kLost:
      return "lost";
  }
  return "unknown";
}

const char* ToString(TrackMethod method) {
  switch (method) {
    case TrackMethod::kLocal:
      return "local";
    case TrackMethod::kPrior:
      return "prior";
    case TrackMethod::kGlobal:
      return "global";
  }
  return "unknown";
}

}  // namespace forestmap::algorithms
