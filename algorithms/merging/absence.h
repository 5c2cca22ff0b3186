#pragma once
// Evidence of absence: which map trees one observation should have seen, and whether it did.
//
// Given the map's trees near an observation, its pose (map_from_sensor, with a 1-sigma
// uncertainty when known) and its detected trees, every map tree is classified as
//   kSeen         it is the nearest tree to a detection, within the association gate;
//   kMissed       the sensor should have seen it and did not: within the sensor's range, not
//                 hidden by a nearer trunk, and no detection within the gate;
//   kNotExpected  out of range (or too near its edge) or in the shadow of a nearer trunk.
// A tree is hidden when its angular extent, seen from the sensor, overlaps the shadow of a
// nearer trunk: half-angle asin((dbh / 2 + margin) / range) of the map's trunks and of the
// observation's own detections (which include stems the map does not have yet), each shadow
// widened by the angle the pose uncertainty can turn it (pose_sigma_xy / range + yaw sigma).
// The sensor's range is stated or learned from the observation's own detections of map trees
// (a high quantile of their horizontal ranges); its detection probability falls linearly with
// range, p(r) = p0 (1 - (1 - far_ratio) r / range), with p0 stated or learned so that the
// expected number of detections of the unhidden map trees in range equals the number seen,
// capped at max_detection_probability (no detector is perfect). An observation that detects
// too few map trees to learn from, and states nothing, gives no evidence (every tree
// kNotExpected). How the classifications accumulate into "gone": absence_evidence.h.
//
// Frames and units as in algorithms/core/geometry.h. Thread-safety: free functions, no state.

#include <cstdint>
#include <span>
#include <vector>

#include "algorithms/core/geometry.h"

namespace forestmap::algorithms {

struct AbsenceOptions {
  double range = 0;                         // m, stated horizontal sensor range; 0: learned
  double range_quantile = 0.9;              // (0, 1], quantile of the detected map trees' ranges
  int min_learn_trees = 5;                  // detected map trees needed to learn range or p0
  double detection_probability = 0;         // [0, 1), stated p0 (at the sensor); 0: learned
  double max_detection_probability = 0.95;  // (0, 1), cap of a learned p0
  double far_ratio = 0.5;                   // [0, 1], p(range) / p0
  double edge_margin = 1.0;                 // m, trees this near the range limit are not expected
  double min_range = 0.5;                   // m, nearer trees are not expected (under the sensor)
  double gate_distance = 0.6;               // m, a detection this near a map tree is a sighting ...
  double gate_sigmas = 3.0;                 // ... or this many sigmas of the pose uncertainty there
  double unknown_dbh = 0.3;                 // m, trunk diameter assumed when a DBH is unknown
  double occlusion_margin = 0.05;           // m, added to every trunk radius (bark, fit error)
  void Check() const;                       // throws std::invalid_argument naming the field
};

// The observation: a pose and what was detected from it.
struct AbsenceObservation {
  Pose3 map_from_sensor = Pose3::Identity();
  double pose_sigma_xy = 0;         // m, 1-sigma horizontal position error per axis of the pose
  double pose_sigma_yaw = 0;        // rad, 1-sigma heading error of the pose
  std::vector<DetectedTree> trees;  // sensor frame; may be empty (a clear-cut)
};

enum class Visibility { kNotExpected, kSeen, kMissed };

const char* ToString(Visibility visibility);

struct TreeVisibility {
  int64_t id = 0;
  Visibility visibility = Visibility::kNotExpected;
  double range = 0;                  // m, horizontal, from the sensor
  double detection_probability = 0;  // p(range) for kMissed and kSeen trees in range, else 0
};

enum class SensorModelSource { kStated, kLearned, kNone };

struct AbsenceResult {
  std::vector<TreeVisibility> trees;  // one per input tree, in input order
  SensorModelSource range_source = SensorModelSource::kNone;
  SensorModelSource probability_source = SensorModelSource::kNone;
  double range = 0;                  // m, used (0 when unknown)
  double detection_probability = 0;  // p0 used (0 when unknown)
  int detected_map_trees = 0;        // established trees with a detection in their gate
  // What p0 was (or would be) learned from: detections, and their expected number per unit p0,
  // of the expected established trees (only those known to stand, when learned_from_standing).
  int learn_seen = 0;
  double learn_weight = 0;
  bool learned_from_standing = false;
  int expected = 0, seen = 0, missed = 0;  // of the trees in range and not hidden
};

// Classifies every tree of `established` (the map's confirmed trees near the sensor: pass at
// least those within range + gate of it) and of `candidates` (trees whose existence is in
// question) for one observation; result.trees holds the established ones, then the candidates.
// Only established trees teach the sensor model and hide others (a candidate may be a false
// stem); `standing` (parallel to `established`, may be shorter or empty) flags those known to
// stand (seen since the survey), which alone teach the detection rate when enough are expected.
// Deterministic. Throws std::invalid_argument for invalid options or a non-finite pose.
AbsenceResult ExpectTrees(std::span<const MapTree> established, std::span<const char> standing,
                          std::span<const MapTree> candidates,
                          const AbsenceObservation& observation,
                          const AbsenceOptions& options = {});

// What one source's frames teach about its sensor, pooled over them: the range of its last frame
// that learned one, and its detection rate over all its frames, from the trees known to stand
// once they weigh min_learn_trees (a felled tree would make the detector look worse than it is).
struct SensorPool {
  double range = 0;                               // m, last learned; 0: none yet
  double standing_seen = 0, standing_weight = 0;  // AbsenceResult::learn_seen, learn_weight
  double all_seen = 0, all_weight = 0;            // summed over frames (from standing or not)
  void Add(const AbsenceResult& frame);
  // `base` with the pooled range and detection probability where it states none (each left 0
  // while nothing is learned).
  AbsenceOptions Apply(const AbsenceOptions& base) const;
};

// The same without candidates.
AbsenceResult ExpectTrees(std::span<const MapTree> map_trees, const AbsenceObservation& observation,
                          const AbsenceOptions& options = {});

}  // namespace forestmap::algorithms
