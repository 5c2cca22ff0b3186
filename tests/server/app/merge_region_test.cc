// The region a merge rebuilds (server/app/merge_region.h), against a store whose rows are laid out
// by hand: whole connected components of rows, grown cell by cell; surveyed trees without rows
// that stand in them; the rows of a tree that spans components; nothing beyond.
#include "server/app/merge_region.h"

#include <gtest/gtest.h>

#include <set>
#include <vector>

#include "storage/sqlite/store.h"

namespace forestmap::server {
namespace {

storage::ObservationRecord Row(int64_t tree, double x, double y, int frame) {
  storage::ObservationRecord row;
  row.tree_id = tree;
  row.source = "drone";
  row.frame_id = frame;
  row.x = x;
  row.y = y;
  row.weight_xy = 400;
  row.sensor_x = x;
  row.sensor_y = y - 5;
  return row;
}

storage::TreeRecord Tree(int64_t id, double x, double y, int64_t observations) {
  storage::TreeRecord tree;
  tree.id = id;
  tree.x = x;
  tree.y = y;
  tree.observations = observations;  // 0: surveyed, never observed (no rows)
  return tree;
}

algorithms::TreeObservation Seed(double x, double y) {
  algorithms::TreeObservation seed;
  seed.position = Eigen::Vector3d(x, y, 0);
  return seed;
}

class MergeRegionTest : public ::testing::Test {
 protected:
  // Trees 1-5: a chain of rows 0.5 m apart along y = 0 from x = 0 to x = 20 (five cells), each
  // tree 8 rows; tree 3 also has one row at (0, -10), next to tree 12's row (0.3 m away).
  // Tree 7: surveyed, no rows, 0.4 m beyond the chain's end. Tree 8: surveyed, no rows, at
  // x = 30. Tree 9: one row at (0, 5), 5 m off the chain.
  void SetUp() override {
    store_.CreateMap("m", "", "");
    store_.WriteTrees("m", {Tree(7, 20.4, 0, 0), Tree(8, 30, 0, 0)}, storage::WriteMode::kAppend);
    store_.Merge("m", storage::MergeNote{}, [](storage::MergeReader&) {
      storage::MapChanges changes;
      for (int k = 0; k <= 40; ++k) {
        const int64_t tree = 1 + std::min(k / 8, 4);
        changes.added_observations.push_back(Row(tree, 0.5 * k, 0, k));
      }
      changes.added_observations.push_back(Row(3, 0, -10, 100));
      changes.added_observations.push_back(Row(12, 0.3, -10, 101));
      changes.added_observations.push_back(Row(9, 0, 5, 102));
      for (int64_t tree : {1, 2, 3, 4, 5}) {
        int64_t rows = 0;
        for (const auto& row : changes.added_observations) rows += row.tree_id == tree;
        changes.put_trees.push_back(Tree(tree, 4.0 * (tree - 1) + 1.75, 0, rows));
      }
      changes.put_trees.push_back(Tree(12, 0.3, -10, 1));
      changes.put_trees.push_back(Tree(9, 0, 5, 1));
      return changes;
    });
  }

  MergeRegion Load(const std::vector<algorithms::TreeObservation>& seeds) {
    MergeRegion region;
    store_.Merge("m", storage::MergeNote{}, [&](storage::MergeReader& reader) {
      region = LoadMergeRegion(reader, seeds, algorithms::MergeOptions{});
      return storage::MapChanges{};
    });
    return region;
  }

  static std::set<int64_t> TreesOfRows(const MergeRegion& region) {
    std::set<int64_t> trees;
    for (const storage::ObservationRecord& row : region.rows) trees.insert(row.tree_id);
    return trees;
  }

  storage::SqliteMapStore store_{":memory:"};
};

TEST_F(MergeRegionTest, GrowsToTheWholeComponentsTheSeedsJoin) {
  const MergeRegion region = Load({Seed(-0.3, 0)});  // links to the chain's first row only
  EXPECT_EQ(region.rows.size(), 43u);                // the chain, and tree 3's far row with
  EXPECT_EQ(TreesOfRows(region), (std::set<int64_t>{1, 2, 3, 4, 5, 12}));  // its neighbour
  ASSERT_EQ(region.unsaved_priors.size(), 1u);  // tree 7 stands at the chain's end
  EXPECT_EQ(region.unsaved_priors[0].tree_id, 7);
  EXPECT_TRUE(region.unsaved_priors[0].prior);
  std::set<int64_t> trees;
  for (const auto& [id, tree] : region.trees) trees.insert(id);
  EXPECT_EQ(trees, (std::set<int64_t>{1, 2, 3, 4, 5, 7, 12}));  // not 8 nor 9
  EXPECT_GT(region.iterations, 3);  // the chain crosses cells one round at a time
}

TEST_F(MergeRegionTest, SeedsAwayFromEveryRowGiveAnEmptyRegion) {
  const MergeRegion region = Load({Seed(10, 2.5), Seed(-50, -50)});
  EXPECT_TRUE(region.rows.empty());
  EXPECT_TRUE(region.trees.empty());
  EXPECT_TRUE(region.unsaved_priors.empty());
}

TEST_F(MergeRegionTest, ASurveyedTreeWithoutRowsIsItsOwnComponent) {
  const MergeRegion region = Load({Seed(30.5, 0)});
  EXPECT_TRUE(region.rows.empty());
  ASSERT_EQ(region.unsaved_priors.size(), 1u);
  EXPECT_EQ(region.unsaved_priors[0].tree_id, 8);
  EXPECT_EQ(region.trees.count(8), 1u);
}

}  // namespace
}  // namespace forestmap::server
