#pragma once
// Conversions between the API's geometry messages (geometry.proto) and Eigen, shared by the
// client and the server so that both ends read poses the same way.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "forestmap/v1/geometry.pb.h"

namespace forestmap {

v1::Vector3 ToProto(const Eigen::Vector3d& v);
Eigen::Vector3d FromProto(const v1::Vector3& v);

// The rotation is normalised on the way in; an absent (or all-zero) rotation is the identity and
// an absent translation is zero.
v1::Pose ToProto(const Eigen::Isometry3d& pose);
Eigen::Isometry3d FromProto(const v1::Pose& pose);

}  // namespace forestmap
