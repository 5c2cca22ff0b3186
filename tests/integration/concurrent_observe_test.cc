// Many drones extend one map at once, through the real wire: four clients upload the four
// quarters of the real Wild_V01 traversal (with their poses, in batches as `forestmap observe`
// sends them) at the same time, and the map they build equals the one a single sequential upload
// of all frames builds, tree by tree: the map is a function of the set of observations
// (server/app/merge_region.h, algorithms::RebuildTrees), not of the order in which they arrived,
// up to folding (server/app/map_merger.h): once a tree holds MergeOptions::fold_rows rows their
// association is fixed, at a moment that depends on the order of the uploads, so a tree where a
// row near two stems went to one stem before the fold in one order and to the other in the other
// may differ. At most 1 in 1,000 trees does.

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <filesystem>
#include <thread>

#include "algorithms/core/kdtree.h"
#include "client/io/tree_csv.h"
#include "client/lib/forestmap_client.h"
#include "server/grpc/server.h"
#include "server/grpc/service.h"
#include "storage/sqlite/store.h"
#include "tests/shared_data.h"

namespace forestmap {
namespace {

const std::string kData = FORESTMAP_SHARED_DATA;
constexpr double kSameTree = 0.01;  // m: "equal" for trees of two merges of the same data
constexpr int kBatch = 25;          // frames per request, as `forestmap observe` sends them
constexpr int kDrones = 4;
constexpr double kMayDiffer = 0.001;  // share of the trees that folding may make differ

std::vector<client::ObservedFrame> WildV01() {
  const std::string dir = kData + "/sequences/Wild_V01";
  const auto poses = client::ReadPosesCsv(dir + "/poses.csv");
  std::vector<client::ObservedFrame> frames;
  for (client::Frame& frame : client::ReadFramesCsv(dir + "/trees.csv")) {
    client::ObservedFrame observed;
    observed.frame_id = frame.frame;
    observed.trees = std::move(frame.trees);
    observed.map_from_sensor = poses.at(frame.frame);
    frames.push_back(std::move(observed));
  }
  return frames;
}

// Uploads frames [first, last) in batches; returns the number of failed requests.
int Upload(client::ForestMapClient& client, const std::string& map, const std::string& source,
           const std::vector<client::ObservedFrame>& frames, size_t first, size_t last) {
  client::ObserveOptions options;
  options.merge_only = true;  // the merge alone is a function of the set of observations
  options.source = source;
  int failures = 0;
  for (size_t begin = first; begin < last; begin += kBatch) {
    const std::vector<client::ObservedFrame> batch(frames.begin() + begin,
                                                   frames.begin() + std::min(last, begin + kBatch));
    try {
      client.Observe(map, batch, options);
    } catch (const std::exception&) {
      ++failures;
    }
  }
  return failures;
}

struct Confirmed {
  std::vector<Eigen::Vector2d> xy;
  std::unique_ptr<algorithms::KdTree<double, 2>> index;
  size_t all_trees = 0;  // candidates too
};

Confirmed ConfirmedTrees(client::ForestMapClient& client, const std::string& map) {
  const client::ExportedTrees exported = client.ExportTrees(map);
  Confirmed out;
  out.all_trees = exported.trees.size();
  std::vector<algorithms::KdTree<double, 2>::Point> points;
  for (size_t i = 0; i < exported.trees.size(); ++i) {
    if (!exported.states[i].confirmed) continue;
    out.xy.emplace_back(exported.trees[i].x, exported.trees[i].y);
    points.push_back({exported.trees[i].x, exported.trees[i].y});
  }
  out.index = std::make_unique<algorithms::KdTree<double, 2>>(std::move(points));
  return out;
}

// Trees of `a` with a tree of `b` within kSameTree.
int Matched(const Confirmed& a, const Confirmed& b) {
  int matched = 0;
  for (const Eigen::Vector2d& p : a.xy) {
    const auto [index, d2] = b.index->Nearest({p.x(), p.y()});
    matched += d2 <= kSameTree * kSameTree;
  }
  return matched;
}

TEST(ConcurrentObserve, FourDronesBuildTheMapOneSequentialUploadBuilds) {
  if (!std::filesystem::exists(kData + "/sequences/Wild_V01/trees.csv")) {
    FORESTMAP_SKIP_WITHOUT_DATA() << "real data missing under " << kData;
  }
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("forestmap_concurrent_" + std::to_string(getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  {
    storage::SqliteMapStore store((dir / "maps.db").string());
    server::ForestMapService service(store, server::ServiceOptions{});
    server::ServerRunner runner("127.0.0.1:0", service);
    client::ForestMapClient client(runner.address());
    const std::vector<client::ObservedFrame> frames = WildV01();
    client.CreateMap("sequential", "", "");
    client.CreateMap("concurrent", "", "");
    EXPECT_EQ(Upload(client, "sequential", "seq", frames, 0, frames.size()), 0);
    std::atomic<int> failures{0};
    std::vector<std::thread> drones;
    for (int q = 0; q < kDrones; ++q) {
      drones.emplace_back([&, q] {
        client::ForestMapClient drone(runner.address());
        // Named against the frame order: the map must not depend on how sources are named.
        const char* source[kDrones] = {"drone-d", "drone-c", "drone-b", "drone-a"};
        failures += Upload(drone, "concurrent", source[q], frames, frames.size() * q / kDrones,
                           frames.size() * (q + 1) / kDrones);
      });
    }
    for (std::thread& drone : drones) drone.join();
    EXPECT_EQ(failures.load(), 0);
    const Confirmed sequential = ConfirmedTrees(client, "sequential");
    const Confirmed concurrent = ConfirmedTrees(client, "concurrent");
    ASSERT_GT(sequential.xy.size(), 10000u);
    // The map is a function of the set of observations up to folding: at most kMayDiffer of
    // the trees differ (beyond 1 cm, or one stem as two trees).
    const double may_differ = kMayDiffer * static_cast<double>(sequential.xy.size());
    EXPECT_NEAR(concurrent.xy.size(), sequential.xy.size(), may_differ);
    EXPECT_LE(sequential.xy.size() - Matched(sequential, concurrent), may_differ);
    EXPECT_LE(concurrent.xy.size() - Matched(concurrent, sequential), may_differ);
    EXPECT_NEAR(concurrent.all_trees, sequential.all_trees, may_differ);
    std::printf(
        "confirmed trees: sequential %zu (%d within 1 cm of a concurrent one), "
        "concurrent %zu (%d); all trees %zu and %zu\n",
        sequential.xy.size(), Matched(sequential, concurrent), concurrent.xy.size(),
        Matched(concurrent, sequential), sequential.all_trees, concurrent.all_trees);
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace forestmap
