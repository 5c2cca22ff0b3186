// The merges of Observe and RemoveSource (server/app/map_merger.h) on an in-memory store, with a
// stretch of forest observed over and over: the rows a merge reads stay bounded however many
// rows its trees have accumulated (their rows fold into summary rows), and folding changes no
// tree, neither as the rows arrive nor after a source's removal or a restore of an older version:
// the trees equal, to 1e-9 m, those of the same writes without folding.

#include "server/app/map_merger.h"

#include <gtest/gtest.h>

#include <random>
#include <string>
#include <vector>

#include "storage/sqlite/store.h"

namespace forestmap::server {
namespace {

constexpr int kSide = 6;          // trees per side of the surveyed grid
constexpr double kSpacing = 3.0;  // m between grid trees
constexpr int kFramesPerObserve = 3;
constexpr double kSame = 1e-9;  // m: equal up to rounding

// Counts the rows a merge reads.
class CountingReader final : public storage::MergeReader {
 public:
  explicit CountingReader(storage::MergeReader& reader) : reader_(reader) {}
  const storage::MapInfo& map() const override { return reader_.map(); }
  std::vector<storage::TreeRecord> TreesInBox(const storage::Extent& box) override {
    return reader_.TreesInBox(box);
  }
  std::vector<storage::TreeRecord> TreesById(std::span<const int64_t> ids) override {
    return reader_.TreesById(ids);
  }
  std::vector<storage::ObservationRecord> ObservationsOfTrees(
      std::span<const int64_t> ids) override {
    return Count(reader_.ObservationsOfTrees(ids));
  }
  std::vector<storage::ObservationRecord> FoldedObservationsOfTrees(
      std::span<const int64_t> ids) override {
    return Count(reader_.FoldedObservationsOfTrees(ids));
  }
  std::vector<storage::ObservationRecord> ObservationsInCells(
      std::span<const storage::ObservationCell> cells) override {
    return Count(reader_.ObservationsInCells(cells));
  }
  std::vector<storage::ObservationRecord> ObservationsOfSource(const std::string& source) override {
    return Count(reader_.ObservationsOfSource(source));
  }
  std::vector<storage::ObservationRecord> ObservationsOfSourceIn(
      const std::string& source, storage::ObservationCell lo,
      storage::ObservationCell hi) override {
    return Count(reader_.ObservationsOfSourceIn(source, lo, hi));
  }
  int64_t NextFreeTreeId() override { return reader_.NextFreeTreeId(); }

  int64_t rows = 0;

 private:
  std::vector<storage::ObservationRecord> Count(std::vector<storage::ObservationRecord> read) {
    rows += static_cast<int64_t>(read.size());
    return read;
  }
  storage::MergeReader& reader_;
};

class MapMergerTest : public ::testing::Test {
 protected:
  MapMergerTest() {
    std::mt19937 random(11);
    std::uniform_real_distribution<double> jitter(-0.3, 0.3), dbh(0.2, 0.45);
    for (int i = 0; i < kSide; ++i) {
      for (int j = 0; j < kSide; ++j) {
        storage::TreeRecord tree;
        tree.x = kSpacing * i + jitter(random);
        tree.y = kSpacing * j + jitter(random);
        tree.z = 0;
        tree.dbh = dbh(random);
        truth_.push_back(tree);
      }
    }
    whole_.fold_rows = 1000000;  // never folds
  }

  void CreateMap(const std::string& name) {
    store_.CreateMap(name, "", "");
    store_.WriteTrees(name, truth_, storage::WriteMode::kAppend);
  }

  // The `k`-th observe of `source`: 3 frames near the middle of the grid, each seeing every tree
  // with 2 cm of noise (and 1 cm on the DBH), different in every frame.
  std::vector<algorithms::FrameObservations> Frames(const std::string& source, int k) {
    std::mt19937 random(1000 * k + static_cast<int>(source.size()) + source.back());
    std::normal_distribution<double> noise(0, 0.02), dbh_noise(0, 0.01);
    std::vector<algorithms::FrameObservations> frames;
    for (int f = 0; f < kFramesPerObserve; ++f) {
      algorithms::FrameObservations frame;
      frame.source = source;
      frame.frame_id = kFramesPerObserve * k + f;
      frame.map_from_sensor = algorithms::PoseFromXyzYaw(6.5 + f, 7.5 - 0.5 * f, 1.5, 0.3 * f);
      for (const storage::TreeRecord& tree : truth_) {
        algorithms::DetectedTree seen;
        const Eigen::Vector3d world(tree.x + noise(random), tree.y + noise(random), 0.0);
        seen.position = frame.map_from_sensor.inverse() * world;
        seen.dbh = *tree.dbh + dbh_noise(random);
        seen.score = 0.8;
        frame.trees.push_back(seen);
      }
      frames.push_back(std::move(frame));
    }
    return frames;
  }

  // Observe `k` of `source` into `map`; returns the rows the merge read.
  int64_t Observe(const std::string& map, const std::string& source, int k,
                  const algorithms::MergeOptions& options) {
    const std::vector<algorithms::FrameObservations> frames = Frames(source, k);
    int64_t rows = 0;
    store_.Merge(map, storage::MergeNote{storage::VersionKind::kObserve, source, std::nullopt},
                 [&](storage::MergeReader& reader) {
                   CountingReader counting(reader);
                   storage::MapChanges changes =
                       MergeFrames(counting, frames, options, true).changes;
                   rows = counting.rows;
                   return changes;
                 });
    return rows;
  }

  void RemoveSource(const std::string& map, const std::string& source,
                    const algorithms::MergeOptions& options) {
    store_.Merge(map, storage::MergeNote{storage::VersionKind::kRemoveSource, source, std::nullopt},
                 [&](storage::MergeReader& reader) {
                   return RemoveSourceChanges(reader, source, options).changes;
                 });
  }

  // The current trees of two maps agree: same ids, positions and DBH within kSame, same counts
  // of observations and status.
  void ExpectSameTrees(const std::string& a, const std::string& b) {
    const std::vector<storage::TreeRecord> ta = store_.ReadMapVersion(a, 0).trees;
    const std::vector<storage::TreeRecord> tb = store_.ReadMapVersion(b, 0).trees;
    ASSERT_EQ(ta.size(), tb.size());
    for (size_t i = 0; i < ta.size(); ++i) {
      EXPECT_EQ(ta[i].id, tb[i].id);
      EXPECT_NEAR(ta[i].x, tb[i].x, kSame) << "tree " << *ta[i].id;
      EXPECT_NEAR(ta[i].y, tb[i].y, kSame) << "tree " << *ta[i].id;
      EXPECT_NEAR(ta[i].dbh.value_or(0), tb[i].dbh.value_or(0), kSame) << "tree " << *ta[i].id;
      EXPECT_EQ(ta[i].observations, tb[i].observations) << "tree " << *ta[i].id;
      EXPECT_EQ(ta[i].status, tb[i].status) << "tree " << *ta[i].id;
    }
  }

  std::vector<storage::TreeRecord> truth_;
  storage::SqliteMapStore store_{":memory:"};
  algorithms::MergeOptions folding_;  // folds at the default fold_rows
  algorithms::MergeOptions whole_;
};

TEST_F(MapMergerTest, AnObserveReadsBoundedRowsHoweverLongItsTreesHistory) {
  CreateMap("m");
  const int trees = kSide * kSide;
  const int fold_rows = folding_.fold_rows;
  int64_t last = 0;
  for (int k = 0; k < 120; ++k) last = Observe("m", "drone", k, folding_);
  // 120 observes left 360 rows per tree; a tree's summary, its rows not folded yet (fewer than
  // fold_rows) and the rows of one observe are what a merge reads of it (some twice: by cell,
  // then by tree).
  int64_t rows = 0;
  store_.Merge("m", storage::MergeNote{}, [&](storage::MergeReader& reader) {
    std::vector<int64_t> ids;
    for (const storage::TreeRecord& tree : reader.TreesInBox({-10, -10, 30, 30})) {
      ids.push_back(*tree.id);
    }
    rows = static_cast<int64_t>(reader.ObservationsOfTrees(ids).size() +
                                reader.FoldedObservationsOfTrees(ids).size());
    return storage::MapChanges{};
  });
  EXPECT_GE(rows, 120 * kFramesPerObserve * trees);
  EXPECT_LE(last, 2 * trees * (fold_rows + 1 + kFramesPerObserve));
}

// A tree beside the region, whose rows were loaded with it, all of them (a neighbour in its cells)
// and not folded (written before folding was), is folded by the observe: the next one reads its
// summary. Its record does not change.
TEST_F(MapMergerTest, ANeighbourWithAHistoryIsFoldedBesideAnObserve) {
  CreateMap("m");
  int64_t id = 0;
  store_.Merge("m", storage::MergeNote{}, [&](storage::MergeReader& reader) {
    storage::MapChanges changes;
    id = reader.NextFreeTreeId();
    storage::TreeRecord tree;
    tree.id = id, tree.x = -2, tree.y = 0.5, tree.observations = 40, tree.dbh = 0.3;
    changes.put_trees.push_back(tree);
    for (int k = 0; k < 40; ++k) {
      storage::ObservationRecord row;
      row.tree_id = id, row.source = "old", row.frame_id = k;
      row.x = -2 + 0.001 * k, row.y = 0.5, row.dbh = 0.3, row.weight_xy = 400;
      row.weight_dbh = 1000, row.sensor_x = -2 + k, row.sensor_y = -5;
      changes.added_observations.push_back(row);
    }
    return changes;
  });
  const storage::TreeRecord before = store_.ReadMapVersion("m", 0).trees.back();
  Observe("m", "drone", 0, folding_);
  const std::vector<int64_t> ids{id};
  store_.Merge("m", storage::MergeNote{}, [&](storage::MergeReader& reader) {
    const std::vector<storage::ObservationRecord> read = reader.ObservationsOfTrees(ids);
    EXPECT_EQ(read.size(), 1u);
    EXPECT_TRUE(!read.empty() && read[0].summary);
    EXPECT_EQ(reader.FoldedObservationsOfTrees(ids).size(), 40u);
    return storage::MapChanges{};
  });
  EXPECT_EQ(store_.ReadMapVersion("m", 0).trees.back(), before);
}

TEST_F(MapMergerTest, FoldingChangesNoTree) {
  CreateMap("folding");
  CreateMap("whole");
  for (int k = 0; k < 40; ++k) {
    Observe("folding", "drone", k, folding_);
    Observe("whole", "drone", k, whole_);
  }
  ExpectSameTrees("folding", "whole");
}

TEST_F(MapMergerTest, ASourceRemovedAfterFoldingLeavesTheTreesOfTheOthers) {
  CreateMap("two");
  CreateMap("one");
  for (int k = 0; k < 30; ++k) {
    Observe("two", "drone-a", k, folding_);
    Observe("two", "drone-b", k, folding_);
    Observe("one", "drone-a", k, whole_);
  }
  RemoveSource("two", "drone-b", folding_);
  ExpectSameTrees("two", "one");
  // And the map folds on from there as if drone-b had never been.
  for (int k = 30; k < 40; ++k) {
    Observe("two", "drone-a", k, folding_);
    Observe("one", "drone-a", k, whole_);
  }
  ExpectSameTrees("two", "one");
}

TEST_F(MapMergerTest, ARestoredVersionBeforeAFoldObservesOnAsWithoutFolding) {
  CreateMap("folding");
  CreateMap("whole");
  int64_t before_fold = 0;
  for (int k = 0; k < 30; ++k) {
    Observe("folding", "drone", k, folding_);
    Observe("whole", "drone", k, whole_);
    if (k == 4) before_fold = store_.GetMap("folding").version;
  }
  ASSERT_EQ(store_.GetMap("whole").version, store_.GetMap("folding").version);
  store_.RestoreVersion("folding", before_fold);
  store_.RestoreVersion("whole", before_fold);
  ExpectSameTrees("folding", "whole");
  for (int k = 30; k < 45; ++k) {
    Observe("folding", "drone", k, folding_);
    Observe("whole", "drone", k, whole_);
  }
  ExpectSameTrees("folding", "whole");
}

}  // namespace
}  // namespace forestmap::server
