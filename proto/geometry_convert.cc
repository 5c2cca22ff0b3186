#include "proto/geometry_convert.h"

namespace forestmap {

v1::Vector3 ToProto(const Eigen::Vector3d& v) {
  v1::Vector3 out;
  out.set_x(v.x());
  out.set_y(v.y());
  out.set_z(v.z());
  return out;
}

Eigen::Vector3d FromProto(const v1::Vector3& v) { return Eigen::Vector3d(v.x(), v.y(), v.z()); }

v1::Pose ToProto(const Eigen::Isometry3d& pose) {
  v1::Pose out;
  *out.mutable_translation() = ToProto(Eigen::Vector3d(pose.translation()));
  const Eigen::Quaterniond q(pose.linear());
  v1::Quaternion* rotation = out.mutable_rotation();
  rotation->set_x(q.x());
  rotation->set_y(q.y());
  rotation->set_z(q.z());
  rotation->set_w(q.w());
  return out;
}

Eigen::Isometry3d FromProto(const v1::Pose& pose) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  if (pose.has_rotation()) {
    const v1::Quaternion& r = pose.rotation();
    const Eigen::Quaterniond q(r.w(), r.x(), r.y(), r.z());
    if (q.norm() > 0) out.linear() = q.normalized().toRotationMatrix();
  }
  if (pose.has_translation()) out.translation() = FromProto(pose.translation());
  return out;
}

}  // namespace forestmap
