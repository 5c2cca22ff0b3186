#pragma once
// Frame-to-map tracking: a drone streams its tree detections and gets a pose for each frame.
//
// Each frame is first matched locally around the predicted pose (the last fix moved by the
// frame's odometry, else by the last frame-to-frame displacement): ICP from a few headings.
// When that fails or would move the prediction too far, the frame is searched for within a radius
// of the prediction, then, after `global_after` frames without a fix, in the whole map. A frame
// with no answer is LOST; the prediction keeps moving with odometry (or the last motion).

#include <optional>

#include "algorithms/core/geometry.h"
#include "algorithms/relocalization/map_index.h"
#include "algorithms/relocalization/relocalizer.h"

namespace forestmap::algorithms {

struct TrackingOptions {
  RelocalizerOptions relocalizer;
  double max_correction = 1.5;      // m, a local fix may move the prediction at most this far
  double yaw_window = 0.15;         // rad, headings tried around the predicted one (plus the
                                    // bearing-alignment peaks, see RefineNear)
  double local_max_rmse = 0.2;      // m, a local fix must fit this well ...
  double local_min_matched = 0.33;  // ... and match this share of the frame's trees in range
  double prior_radius = 10.0;       // m, search radius around the prediction after a local miss
  double radius_growth = 5.0;       // m, added to the radius per frame without a fix
  int global_after = 2;             // frames without a fix before the whole map is searched
  // Without odometry, predict the position with the last frame-to-frame displacement (the
  // heading with the last fix's: a carried sensor's heading wobbles, its path does not).
  bool constant_velocity = true;
  void Check() const;
};

struct TrackingFrame {
  RelocalizeQuery query;  // trees and gravity of the frame; its prior is ignored
  // Motion since the previous frame, previous_sensor_from_sensor (odometry), when known.
  std::optional<Pose3> odometry;
};

enum class TrackState {
  kTracking,   // localized by local matching around the prediction
  kRecovered,  // localized by a search (first frame, after a miss, or after a lost track)
  kLost,       // no pose for this frame
};

enum class TrackMethod { kLocal, kPrior, kGlobal };

struct TrackingStep {
  TrackState state = TrackState::kLost;
  TrackMethod method = TrackMethod::kGlobal;  // how the answer (or the last attempt) was found
  RelocalizeResult result;                    // pose, inliers, matches of this frame
  int frames_lost = 0;  // consecutive frames without a fix, this one included (0 when localized)
};

// One drone's tracking session. Not thread-safe: one per stream. The map index is passed per
// frame so that a session can move to a newer map version.
class Tracker {
 public:
  explicit Tracker(const TrackingOptions& options = {});

  TrackingStep Step(const MapIndex& index, const TrackingFrame& frame);

  // The last fix moved by the motion since, if there ever was a fix.
  const std::optional<Pose3>& prediction() const { return predicted_; }

 private:
  std::optional<TrackingStep> TryLocal(const MapIndex& index, const TrackingFrame& frame) const;

  TrackingOptions options_;
  std::optional<Pose3> last_fix_;            // map_from_sensor of the last localized frame
  std::optional<Pose3> predicted_;           // map_from_sensor expected for the next frame's sensor
  std::optional<Eigen::Vector3d> velocity_;  // m per frame, map frame, of the last two fixes
  int frames_lost_ = 0;
};

const char* ToString(TrackState state);
const char* ToString(TrackMethod method);

}  // namespace forestmap::algorithms
