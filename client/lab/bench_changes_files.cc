#include "client/lab/bench_changes_files.h"

#include <iomanip>
#include <nlohmann/json.hpp>

namespace forestmap::client {

PassWriter::PassWriter(const std::string& dir, int pass)
    : trees_(dir + "/pass" + std::to_string(pass) + "_trees.csv"),
      poses_(dir + "/pass" + std::to_string(pass) + "_poses.csv") {
  trees_ << std::setprecision(10) << "frame,x,y,z,dbh\n";
  poses_ << std::setprecision(12) << "frame,timestamp,x,y,z,qx,qy,qz,qw\n";
}

void PassWriter::Add(const algorithms::FrameObservations& frame) {
  for (const algorithms::DetectedTree& tree : frame.trees) {
    trees_ << frame.frame_id << "," << tree.position.x() << "," << tree.position.y() << ","
           << tree.position.z() << ",";
    if (algorithms::IsKnown(tree.dbh)) trees_ << tree.dbh;
    trees_ << "\n";
  }
  const Eigen::Vector3d t = frame.map_from_sensor.translation();
  const Eigen::Quaterniond q(frame.map_from_sensor.linear());
  poses_ << frame.frame_id << ",0," << t.x() << "," << t.y() << "," << t.z() << "," << q.x() << ","
         << q.y() << "," << q.z() << "," << q.w() << "\n";
}

void WriteChangesTruth(const std::string& dir, const std::set<int64_t>& felled,
                       const std::vector<algorithms::MapTree>& ingrowth, double growth) {
  nlohmann::ordered_json truth;
  truth["felled"] = felled;
  nlohmann::json trees = nlohmann::json::array();
  for (const algorithms::MapTree& tree : ingrowth) {
    trees.push_back({tree.position.x(), tree.position.y(), tree.dbh});
  }
  truth["new_trees"] = trees;
  truth["growth"] = growth;
  std::ofstream(dir + "/truth.json") << truth.dump() << "\n";
}

}  // namespace forestmap::client
