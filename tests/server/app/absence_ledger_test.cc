// The evidence of absence through Observe (server/app/shared_map.h, absence_ledger.h) on an
// in-memory store: a surveyed plot whose trees are the truth, part of them felled; drones fly
// it and detect the standing trees near them. Felled trees leave the map once several sources
// missed them, never after one or two; standing trees stay and carry the date they were last
// seen; the removal log names each removed tree with its evidence; a restore brings the trees
// back; a frame with a pose and no trees is evidence too; a false stem seen once is retired by
// the same request's later frames; real frames of an unchanged forest remove almost nothing.

#include "server/app/absence_ledger.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "client/io/tree_csv.h"
#include "server/app/shared_map.h"
#include "storage/sqlite/store.h"
#include "tests/shared_data.h"

namespace forestmap::server {
namespace {

constexpr double kPlot = 60;         // m, square plot
constexpr double kSensorRange = 12;  // m, what the drones detect
constexpr double kStep = 4;          // m between frames along a line

class AbsenceLedgerTest : public ::testing::Test {
 protected:
  AbsenceLedgerTest() {
    std::mt19937 random(11);
    std::uniform_real_distribution<double> metres(0, kPlot), dbh(0.2, 0.4);
    std::vector<storage::TreeRecord> survey;
    while (survey.size() < 150) {
      storage::TreeRecord tree;
      tree.x = metres(random);
      tree.y = metres(random);
      tree.z = 0;
      tree.dbh = dbh(random);
      bool apart = true;
      for (const storage::TreeRecord& t : survey) {
        apart = apart && std::hypot(t.x - tree.x, t.y - tree.y) > 3.0;
      }
      if (apart) survey.push_back(tree);
    }
    store_.CreateMap("plot", "", "");
    store_.WriteTrees("plot", survey, storage::WriteMode::kAppend);  // version 2
    for (const storage::TreeRecord& tree : store_.ReadMap("plot").trees) {
      // Every fifth tree is felled.
      (*tree.id % 5 == 0 ? felled_ : standing_).push_back(tree);
    }
  }

  // A frame at (x, y) detecting the standing trees within kSensorRange (and `extra`, map frame).
  ObserveFrame Frame(int64_t id, double x, double y, std::vector<Eigen::Vector2d> extra = {}) {
    ObserveFrame frame;
    frame.has_pose = true;
    frame.observations.frame_id = id;
    frame.observations.map_from_sensor = algorithms::PoseFromXyzYaw(x, y, 1.5, 0.3);
    const algorithms::Pose3 sensor_from_map = frame.observations.map_from_sensor.inverse();
    for (const storage::TreeRecord& tree : standing_) {
      if (std::hypot(tree.x - x, tree.y - y) > kSensorRange) continue;
      algorithms::DetectedTree seen;
      seen.position = sensor_from_map * Eigen::Vector3d(tree.x, tree.y, 0);
      seen.dbh = *tree.dbh;
      frame.observations.trees.push_back(seen);
    }
    for (const Eigen::Vector2d& p : extra) {
      algorithms::DetectedTree seen;
      seen.position = sensor_from_map * Eigen::Vector3d(p.x(), p.y(), 0);
      seen.dbh = 0.25;
      frame.observations.trees.push_back(seen);
    }
    return frame;
  }

  // One pass of `source` over the plot: lines 10 m apart, a frame every kStep m, in requests of
  // 20 frames.
  void Fly(const std::string& source) {
    std::vector<ObserveFrame> frames;
    int64_t id = 0;
    for (double y = 5; y < kPlot; y += 10) {
      for (double x = 0; x <= kPlot; x += kStep) {
        frames.push_back(Frame(++id, x, y));
        if (frames.size() == 20) Observe(source, std::move(frames)), frames.clear();
      }
    }
    if (!frames.empty()) Observe(source, std::move(frames));
  }

  ObserveOutcome Observe(const std::string& source, std::vector<ObserveFrame> frames,
                         double range = 0, double probability = 0) {
    ObserveCall call;
    call.write.rpc = "Observe";
    call.map_name = "plot";
    call.source = source;
    call.frames = std::move(frames);
    call.sensor_range = range;
    call.detection_probability = probability;
    return ApplyObserve(
               store_, index_cache_, call, options_, [](const ObserveOutcome&) { return ""; },
               [] { return false; })
        .outcome;
  }

  std::set<int64_t> Ids() {
    std::set<int64_t> ids;
    for (const storage::TreeRecord& tree : store_.ReadMap("plot").trees) ids.insert(*tree.id);
    return ids;
  }
  int Present(const std::vector<storage::TreeRecord>& trees) {
    const std::set<int64_t> ids = Ids();
    int present = 0;
    for (const storage::TreeRecord& tree : trees) present += ids.count(*tree.id);
    return present;
  }

  storage::SqliteMapStore store_{":memory:"};
  MapIndexCache index_cache_{store_};
  SharedMapOptions options_;
  std::vector<storage::TreeRecord> standing_, felled_;
};

TEST_F(AbsenceLedgerTest, FelledTreesLeaveTheMapOnlyOnceSeveralSourcesMissedThem) {
  ASSERT_GE(felled_.size(), 20u);
  Fly("drone-1");
  Fly("drone-2");
  EXPECT_EQ(Present(felled_), static_cast<int>(felled_.size())) << "two sources removed a tree";
  Fly("drone-3");
  Fly("drone-4");
  // Trees at the plot's edge may be out of every view; the rest are gone.
  EXPECT_GE(felled_.size() - Present(felled_), felled_.size() * 9 / 10);
  EXPECT_EQ(Present(standing_), static_cast<int>(standing_.size()));
}

TEST_F(AbsenceLedgerTest, StandingTreesCarryTheDateTheyWereLastSeen) {
  const int64_t before = std::chrono::duration_cast<std::chrono::milliseconds>(
                             std::chrono::system_clock::now().time_since_epoch())
                             .count();
  Fly("drone-1");
  int seen = 0;
  for (const storage::TreeRecord& tree : store_.ReadMap("plot").trees) {
    if (*tree.id % 5 == 0) continue;
    seen += tree.last_seen_unix_ms.has_value();
    if (tree.last_seen_unix_ms) {
      EXPECT_GE(*tree.last_seen_unix_ms, before);
    }
  }
  EXPECT_GE(seen, static_cast<int>(standing_.size()) * 9 / 10);
}

TEST_F(AbsenceLedgerTest, TheRemovalLogNamesEachRemovedTreeAndARestoreBringsItBack) {
  for (const char* source : {"drone-1", "drone-2", "drone-3", "drone-4"}) Fly(source);
  const std::set<int64_t> ids = Ids();
  std::set<int64_t> removed;
  for (const storage::TreeRecord& tree : felled_) {
    if (ids.count(*tree.id) == 0) removed.insert(*tree.id);
  }
  std::set<int64_t> logged;
  for (const storage::TreeRemoval& removal : store_.ListRemovals("plot", 2)) {
    logged.insert(removal.tree_id);
    const nlohmann::json note = nlohmann::json::parse(removal.evidence);
    EXPECT_EQ(note.at("kind"), "removed");
    EXPECT_GE(note.at("log_likelihood_ratio").get<double>(), note.at("threshold").get<double>());
    EXPECT_GE(note.at("groups").size(), 3u) << "fewer than three sources removed a tree";
  }
  EXPECT_EQ(logged, removed);
  store_.RestoreVersion("plot", 2);
  EXPECT_EQ(Present(felled_), static_cast<int>(felled_.size()));
}

TEST_F(AbsenceLedgerTest, FramesWithAPoseAndNoTreesAreEvidenceOfAClearCut) {
  // Every tree around the plot's centre cut: three frames there see nothing.
  std::vector<ObserveFrame> empty;
  for (const auto& [x, y] : {std::pair{30.0, 30.0}, {31.0, 30.0}, {30.0, 31.0}}) {
    ObserveFrame& frame = empty.emplace_back();
    frame.has_pose = true;
    frame.observations.frame_id = static_cast<int64_t>(empty.size());
    frame.observations.map_from_sensor = algorithms::PoseFromXyzYaw(x, y, 1.5, 0);
  }
  const auto near_centre = [&](double radius) {
    int count = 0;
    for (const storage::TreeRecord& tree : store_.ReadMap("plot").trees) {
      count += std::hypot(tree.x - 30, tree.y - 30) <= radius;
    }
    return count;
  };
  const int near_before = near_centre(8);
  const int far_before = near_centre(1e9) - near_centre(kSensorRange);
  const ObserveOutcome outcome = Observe("drone-1", empty, kSensorRange, 0.9);
  ASSERT_EQ(outcome.frames.size(), 3u);
  EXPECT_TRUE(outcome.frames[0].merged) << outcome.frames[0].detail;
  EXPECT_GT(outcome.frames[0].counts.missed, 0);
  EXPECT_EQ(outcome.map.version, 3) << "the misses are stored as a new version";
  for (const char* source : {"drone-2", "drone-3", "drone-4"}) {
    Observe(source, empty, kSensorRange, 0.9);
  }
  // Four sources remove most trees near the centre (those behind nearer trunks were never
  // expected), none beyond the stated range.
  EXPECT_LE(near_centre(8) * 4, near_before);
  EXPECT_EQ(near_centre(1e9) - near_centre(kSensorRange), far_before);
}

TEST_F(AbsenceLedgerTest, AFalseStemSeenOnceIsRetiredByTheLaterFramesOfThePass) {
  const Eigen::Vector2d ghost(31.3, 28.9);  // no tree there
  std::vector<ObserveFrame> frames = {Frame(1, 26, 25, {ghost})};
  for (int k = 1; k <= 4; ++k) frames.push_back(Frame(1 + k, 26 + k, 25));
  const ObserveOutcome outcome = Observe("drone-1", std::move(frames));
  EXPECT_EQ(outcome.frames[0].counts.added, 1);
  int removed = 0;
  for (const FrameOutcome& frame : outcome.frames) removed += frame.counts.removed;
  EXPECT_EQ(removed, 1);
  for (const storage::TreeRecord& tree : store_.ReadMap("plot").trees) {
    EXPECT_GT(std::hypot(tree.x - ghost.x(), tree.y - ghost.y()), 1.0);
  }
}

// Real frames of a forest that did not change (Wild_V02, ground-truth poses) into the map of the
// same day (Wild_V01), three drones of 100 frames each: the trees the merge moves, merges and
// splits carry their evidence through, and almost no tree is removed.
TEST(AbsenceRealFramesTest, AnUnchangedForestKeepsItsTrees) {
  const std::string data = std::string(FORESTMAP_SHARED_DATA) + "/sequences/";
  if (!std::filesystem::exists(data + "Wild_V02/poses.csv")) {
    FORESTMAP_SKIP_WITHOUT_DATA() << "missing " << data;
  }
  storage::SqliteMapStore store(":memory:");
  store.CreateMap("wild", "", "");
  std::vector<storage::TreeRecord> survey;
  for (const client::MapTreeRow& row : client::ReadMapTreesCsv(data + "Wild_V01/map.csv")) {
    storage::TreeRecord tree;
    tree.id = row.id;
    tree.x = row.x;
    tree.y = row.y;
    tree.z = row.z;
    tree.dbh = row.dbh;
    survey.push_back(tree);
  }
  store.WriteTrees("wild", survey, storage::WriteMode::kAppend);
  const auto poses = client::ReadPosesCsv(data + "Wild_V02/poses.csv");
  MapIndexCache index_cache(store);
  for (int drone = 0; drone < 3; ++drone) {
    ObserveCall call;
    call.write.rpc = "Observe";
    call.map_name = "wild";
    call.source = "drone-" + std::to_string(drone);
    for (const client::Frame& frame : client::ReadFramesCsv(data + "Wild_V02/trees.csv")) {
      if (frame.frame / 100 != drone || !poses.count(frame.frame)) continue;
      ObserveFrame& observed = call.frames.emplace_back();
      observed.has_pose = true;
      observed.pose_sigma = {0.1, 0.2 * M_PI / 180};
      observed.observations.frame_id = frame.frame;
      observed.observations.trees = frame.trees;
      observed.observations.map_from_sensor = poses.at(frame.frame);
      if (call.frames.size() == 50) {
        ASSERT_NO_THROW(ApplyObserve(
            store, index_cache, call, SharedMapOptions{}, [](const ObserveOutcome&) { return ""; },
            [] { return false; }));
        call.frames.clear();
      }
    }
  }
  std::set<int64_t> left;
  for (const storage::TreeRecord& tree : store.ReadMap("wild").trees) left.insert(*tree.id);
  int removed = 0;
  for (const storage::TreeRecord& tree : survey) removed += left.count(*tree.id) == 0;
  EXPECT_LE(removed, static_cast<int>(survey.size()) / 200) << "more than 0.5% removed";
}

TEST(TreeEvidenceTest, StoredEvidenceReadsBackAndGarbageReadsAsNone) {
  algorithms::TreeEvidence evidence;
  algorithms::AddSighting(evidence, "a", 1000);
  algorithms::AddMiss(evidence, "b", 0.8);
  algorithms::AddMiss(evidence, "b", 0.5);
  storage::TreeRecord tree;
  SetEvidence(tree, evidence);
  const algorithms::TreeEvidence back = ToTreeEvidence(tree);
  EXPECT_EQ(back.last_seen, 1000);
  EXPECT_EQ(back.sightings, 1);
  EXPECT_EQ(back.misses, 2);
  ASSERT_EQ(back.groups.size(), 1u);
  EXPECT_DOUBLE_EQ(back.groups[0].log_all_missed, evidence.groups[0].log_all_missed);
  for (const char* garbage : {"", "{", "[1]", R"({"groups": [[1]]})", "\xff"}) {
    tree.evidence = garbage;
    EXPECT_TRUE(ToTreeEvidence(tree).groups.empty()) << garbage;
  }
}

}  // namespace
}  // namespace forestmap::server
