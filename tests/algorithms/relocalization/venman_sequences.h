#pragma once

// The real sequences (../shared/data/sequences) read by the real-data relocalization and tracking
// tests, and the offset between the ground truths of the two Venman traversals.

#include <cmath>
#include <string>

#include "algorithms/core/geometry.h"

namespace forestmap::algorithms {

inline const std::string kSequences = std::string(FORESTMAP_SHARED_DATA) + "/sequences/";

// Wild_V02's ground truth is offset from Wild_V01's (../shared/data/README.md):
// map_V01_from_map_V02 = translation (0.051, 0.102, -0.039) m, yaw -0.014 deg.
inline const Pose3 kV01FromV02 = PoseFromXyzYaw(0.051, 0.102, -0.039, -0.014 * M_PI / 180.0);

}  // namespace forestmap::algorithms
