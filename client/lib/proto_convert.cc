#include "client/lib/proto_convert.h"

namespace forestmap::client {

v1::Tree ToProto(const MapTreeRow& row) {
  v1::Tree tree;
  if (row.id) tree.set_id(*row.id);
  tree.set_x(row.x);
  tree.set_y(row.y);
  if (row.z) tree.set_z(*row.z);
  if (row.dbh) tree.set_dbh(*row.dbh);
  tree.mutable_attributes()->insert(row.attributes.begin(), row.attributes.end());
  for (const std::string& name : row.null_attributes) tree.add_null_attributes(name);
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
  row.null_attributes.insert(tree.null_attributes().begin(), tree.null_attributes().end());
  return row;
}

v1::DetectedTree ToProto(const algorithms::DetectedTree& tree) {
  v1::DetectedTree out;
  *out.mutable_position() = ToProto(tree.position);
  if (algorithms::IsKnown(tree.dbh)) out.set_dbh(tree.dbh);
  if (tree.HasAxis()) *out.mutable_axis() = ToProto(tree.axis);
  if (algorithms::IsKnown(tree.score)) out.set_score(tree.score);
  return out;
}

}  // namespace forestmap::client
