// Two real drone scans (sloam_uav_ouster: an Ouster 64-beam on a quadrotor over a forest, the
// "moving" pair t0 and t1 with their odometry in poses.txt): the trunks detected in t1 relocalize
// against the trunks detected in t0 with the relative pose the odometry measured.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "algorithms/detection/trunk_detection.h"
#include "algorithms/relocalization/relocalizer.h"
#include "client/io/scan_io.h"
#include "tests/shared_data.h"

namespace forestmap::algorithms {
namespace {

const std::string kDir = std::string(FORESTMAP_SHARED_DATA) + "/scans/sloam_uav_ouster/";

// The scan of one instant: its tree points and its ground points (stored as two clouds).
PointCloud Scan(const std::string& instant) {
  PointCloud cloud = client::ReadScan(kDir + "moving_tree_" + instant + ".pcd");
  const PointCloud ground = client::ReadScan(kDir + "moving_ground_" + instant + ".pcd");
  std::erase_if(cloud.points, [](const Eigen::Vector3f& p) { return !p.allFinite(); });
  cloud.points.insert(cloud.points.end(), ground.points.begin(), ground.points.end());
  cloud.intensity.clear();
  cloud.ring.clear();
  cloud.width = static_cast<uint32_t>(cloud.points.size());
  cloud.height = 1;
  return cloud;
}

// The two odometry poses of poses.txt (nav_msgs/Odometry YAML): pose.pose of t0, then of t1.
std::vector<Pose3> OdometryPoses() {
  std::ifstream in(kDir + "poses.txt");
  std::vector<Pose3> poses;
  std::string line;
  auto value = [&in, &line] {
    std::getline(in, line);
    return std::stod(line.substr(line.find(':') + 1));
  };
  while (std::getline(in, line)) {
    if (line.find("position:") == std::string::npos) continue;
    const double x = value(), y = value(), z = value();
    std::getline(in, line);  // orientation:
    const double qx = value(), qy = value(), qz = value(), qw = value();
    Pose3 pose = Pose3::Identity();
    pose.linear() = Eigen::Quaterniond(qw, qx, qy, qz).normalized().toRotationMatrix();
    pose.translation() = Eigen::Vector3d(x, y, z);
    poses.push_back(pose);
  }
  return poses;
}

TEST(DroneScanPair, TrunksOfTheSecondScanRelocalizeWithTheOdometrysRelativePose) {
  if (!std::filesystem::exists(kDir + "poses.txt"))
    FORESTMAP_SKIP_WITHOUT_DATA() << "missing " << kDir;
  const std::vector<Pose3> odometry = OdometryPoses();
  ASSERT_EQ(odometry.size(), 2u);
  const Pose3 t0_from_t1 = odometry[0].inverse() * odometry[1];

  const TrunkDetectionResult t0 = DetectTrunks(Scan("t0"), {});
  const TrunkDetectionResult t1 = DetectTrunks(Scan("t1"), {});
  ASSERT_GE(t0.trees.size(), 10u);
  ASSERT_GE(t1.trees.size(), 10u);
  std::vector<MapTree> map;  // t0's trunks, in t0's sensor frame
  for (size_t i = 0; i < t0.trees.size(); ++i) {
    map.push_back({static_cast<int64_t>(i), t0.trees[i].tree.position, t0.trees[i].tree.dbh});
  }
  RelocalizeQuery query;
  for (const DetectedTrunk& trunk : t1.trees) query.trees.push_back(trunk.tree);
  const RelocalizeResult result = Relocalize(MapIndex(map), query);
  ASSERT_EQ(result.status, RelocalizeStatus::kLocalized) << result.detail;

  const Eigen::Vector2d error =
      (result.map_from_sensor.translation() - t0_from_t1.translation()).head<2>();
  const double yaw_error =
      std::abs(WrapAngle(YawOf(result.map_from_sensor.linear()) - YawOf(t0_from_t1.linear())));
  std::cout << "t1 vs t0: " << t0.trees.size() << " / " << t1.trees.size() << " trunks, "
            << result.inliers << " matched; odometry moved "
            << t0_from_t1.translation().head<2>().norm() << " m; error " << error.norm() << " m, "
            << yaw_error * 180 / M_PI << " deg\n";
  EXPECT_LE(error.norm(), 0.3);
  EXPECT_LE(yaw_error, 3 * M_PI / 180);
}

}  // namespace
}  // namespace forestmap::algorithms
