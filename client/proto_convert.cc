#include "client/proto_convert.h"

namespace forestmap::client {
namespace {

void SetVector(const Eigen::Vector3d& v, v1::Vector3* out) {
  out->set_x(v.x());
  out->set_y(v.y());
  out->set_z(v.z());
}

}  // namespace

v1::Tree ToProto(const MapTreeRow& row) {
  v1::Tree tree;
  if (row.id) tree.set_id(*row.id);
  tree.set_x(row.x);
  tree.set_y(row.y);
  if (row.z) tree.set_z(*row.z);
  if (row.dbh) tree.set_dbh(*row.dbh);
  tree.mutable_attributes()->insert(row.attributes.begin(), row.attributes.end());
  return tree;
}

MapTreeRow FromProto(const v1::Tree& tree) {
  MapTreeRow row;
  if (tree.has_id()) row.id = tree.id();
  row.x = tree.x();
  row.y = tree.y();
  if (tree.has_z()) row.z = tree.z();
  if (tree.has_dbh()) row.dbh = tree.dbh();
  row.attributes.insert(tree.attributes().begin(), tree.attributes().end());
  return row;
}

v1::DetectedTree ToProto(const algorithms::DetectedTree& tree) {
  v1::DetectedTree out;
  SetVector(tree.position, out.mutable_position());
  if (algorithms::IsKnown(tree.dbh)) out.set_dbh(tree.dbh);
  if (tree.HasAxis()) SetVector(tree.axis, out.mutable_axis());
  if (algorithms::IsKnown(tree.score)) out.set_score(tree.score);
  return out;
}

v1::Pose ToProto(const algorithms::Pose3& pose) {
  v1::Pose out;
  SetVector(pose.translation(), out.mutable_translation());
  const Eigen::Quaterniond q(pose.linear());
  out.mutable_rotation()->set_x(q.x());
  out.mutable_rotation()->set_y(q.y());
  out.mutable_rotation()->set_z(q.z());
  out.mutable_rotation()->set_w(q.w());
  return out;
}

algorithms::Pose3 FromProto(const v1::Pose& pose) {
  const v1::Quaternion& r = pose.rotation();
  Eigen::Quaterniond q(r.w(), r.x(), r.y(), r.z());
  // An unset rotation (all zero) is the identity rather than a division by zero.
  q = q.norm() > 0 ? q.normalized() : Eigen::Quaterniond::Identity();
  algorithms::Pose3 out = algorithms::Pose3::Identity();
  out.linear() = q.toRotationMatrix();
  out.translation() =
      Eigen::Vector3d(pose.translation().x(), pose.translation().y(), pose.translation().z());
  return out;
}

}  // namespace forestmap::client
