// MapStore semantics on every backend (SQLite in memory, PostgreSQL on the test cluster): maps,
// errors, versions, writes, ids, exact round trips and the spatial index against brute force.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "tests/storage/store_backends.h"
#include "tests/storage/store_test_util.h"

namespace forestmap::storage {
namespace {

using Code = StorageError::Code;

class MapStoreTest : public ::testing::TestWithParam<Backend> {
 protected:
  TestStore test_store_{GetParam()};
  MapStore& store_ = *test_store_;
};
INSTANTIATE_TEST_SUITE_P(Backends, MapStoreTest, kAllBackends, BackendName);

TEST_P(MapStoreTest, CreateListGetDelete) {
  const MapInfo created = store_.CreateMap("plot-b", "second plot", "EPSG:32633");
  store_.CreateMap("plot-a", "", "");
  store_.CreateMap("Plot_c.2", "", "");
  EXPECT_EQ(created.name, "plot-b");
  EXPECT_EQ(created.description, "second plot");
  EXPECT_EQ(created.crs, "EPSG:32633");
  EXPECT_EQ(created.version, 1);
  EXPECT_EQ(created.tree_count, 0);
  EXPECT_FALSE(created.extent.has_value());
  EXPECT_GT(created.created_unix_ms, 0);
  EXPECT_EQ(created.created_unix_ms, created.updated_unix_ms);

  const MapInfo got = store_.GetMap("plot-b");
  EXPECT_EQ(got.description, "second plot");
  EXPECT_EQ(got.crs, "EPSG:32633");
  EXPECT_EQ(got.version, 1);
  EXPECT_EQ(got.created_unix_ms, created.created_unix_ms);

  std::vector<std::string> names;
  for (const MapInfo& info : store_.ListMaps()) names.push_back(info.name);
  EXPECT_EQ(names, (std::vector<std::string>{"Plot_c.2", "plot-a", "plot-b"}));  // bytewise

  store_.DeleteMap("plot-b");
  ExpectError([&] { store_.GetMap("plot-b"); }, Code::kNotFound, "map 'plot-b' does not exist");
  EXPECT_EQ(store_.ListMaps().size(), 2u);
  // The name is free again.
  EXPECT_EQ(store_.CreateMap("plot-b", "again", "").version, 1);
}

TEST_P(MapStoreTest, ErrorsCarryCodeAndMapName) {
  store_.CreateMap("a", "", "");
  ExpectError([&] { store_.CreateMap("a", "", ""); }, Code::kAlreadyExists,
              "map 'a' already exists");
  const std::string missing = "map 'nope' does not exist";
  ExpectError([&] { store_.GetMap("nope"); }, Code::kNotFound, missing);
  ExpectError([&] { store_.DeleteMap("nope"); }, Code::kNotFound, missing);
  ExpectError([&] { store_.ReadMap("nope"); }, Code::kNotFound, missing);
  ExpectError([&] { store_.WriteTrees("nope", {Tree(1, 0, 0)}, WriteMode::kAppend); },
              Code::kNotFound, missing);
  ExpectError([&] { store_.TreesInBox("nope", Extent{0, 0, 1, 1}); }, Code::kNotFound, missing);
}

TEST_P(MapStoreTest, InvalidNamesAreRejectedWithTheRule) {
  EXPECT_EQ(ValidateMapName("Aa0_.-"), "");
  EXPECT_EQ(ValidateMapName(std::string(128, 'x')), "");
  EXPECT_NE(ValidateMapName("").find("empty"), std::string::npos);
  EXPECT_NE(ValidateMapName(std::string(129, 'x')).find("128"), std::string::npos);
  EXPECT_NE(ValidateMapName("a b").find("character 2"), std::string::npos);

  for (const std::string& name : {std::string(), std::string(129, 'x'), std::string("a b"),
                                  std::string("a/b"), std::string("pl\xc3\xa4t"),
                                  std::string("a'; DROP TABLE maps; --"), std::string("a\0b", 3)}) {
    ExpectError([&] { store_.CreateMap(name, "", ""); }, Code::kInvalidArgument,
                "invalid map name");
    ExpectError([&] { store_.GetMap(name); }, Code::kInvalidArgument, "invalid map name");
    ExpectError([&] { store_.WriteTrees(name, {}, WriteMode::kAppend); }, Code::kInvalidArgument,
                "invalid map name");
  }
  EXPECT_TRUE(store_.ListMaps().empty());
}

TEST_P(MapStoreTest, EveryChangeBumpsVersionAndKeepsCountAndExtent) {
  store_.CreateMap("m", "", "");
  MapInfo info =
      store_.WriteTrees("m", {Tree(1, 1, 2), Tree(2, -3, 5), Tree(3, 4, -1)}, WriteMode::kAppend);
  EXPECT_EQ(info.version, 2);
  EXPECT_EQ(info.tree_count, 3);
  ASSERT_TRUE(info.extent.has_value());
  EXPECT_EQ(info.extent->min_x, -3);
  EXPECT_EQ(info.extent->min_y, -1);
  EXPECT_EQ(info.extent->max_x, 4);
  EXPECT_EQ(info.extent->max_y, 5);
  EXPECT_GE(info.updated_unix_ms, info.created_unix_ms);

  // An empty append changes nothing and keeps the version.
  EXPECT_EQ(store_.WriteTrees("m", {}, WriteMode::kAppend).version, 2);

  info = store_.WriteTrees("m", {Tree(4, 10, 0.5)}, WriteMode::kAppend);
  EXPECT_EQ(info.version, 3);
  EXPECT_EQ(info.tree_count, 4);
  EXPECT_EQ(info.extent->max_x, 10);
  EXPECT_EQ(info.extent->min_x, -3);

  info = store_.WriteTrees("m", {Tree(9, 0.25, 0.75)}, WriteMode::kReplace);
  EXPECT_EQ(info.version, 4);
  EXPECT_EQ(info.tree_count, 1);
  EXPECT_EQ(info.extent->min_x, 0.25);
  EXPECT_EQ(info.extent->max_x, 0.25);
  EXPECT_EQ(info.extent->min_y, 0.75);
  EXPECT_EQ(info.extent->max_y, 0.75);

  info = store_.WriteTrees("m", {}, WriteMode::kReplace);  // clears: a change
  EXPECT_EQ(info.version, 5);
  EXPECT_EQ(info.tree_count, 0);
  EXPECT_FALSE(info.extent.has_value());
  EXPECT_EQ(store_.WriteTrees("m", {}, WriteMode::kReplace).version, 5);  // already empty

  const MapInfo stored = store_.GetMap("m");
  EXPECT_EQ(stored.version, 5);
  EXPECT_EQ(stored.tree_count, 0);
  EXPECT_FALSE(stored.extent.has_value());
}

TEST_P(MapStoreTest, AppendAddsAndReplaceSubstitutes) {
  store_.CreateMap("m", "", "");
  store_.WriteTrees("m", {Tree(5, 0, 0), Tree(2, 1, 1)}, WriteMode::kAppend);
  store_.WriteTrees("m", {Tree(3, 2, 2)}, WriteMode::kAppend);
  MapSnapshot snapshot = store_.ReadMap("m");
  EXPECT_EQ(Ids(snapshot.trees), (std::vector<int64_t>{2, 3, 5}));  // sorted by id
  EXPECT_EQ(snapshot.info.tree_count, 3);
  EXPECT_EQ(snapshot.trees[2], Tree(5, 0, 0));

  store_.WriteTrees("m", {Tree(5, 7, 7), Tree(8, 8, 8)}, WriteMode::kReplace);
  snapshot = store_.ReadMap("m");
  EXPECT_EQ(snapshot.trees, (std::vector<TreeRecord>{Tree(5, 7, 7), Tree(8, 8, 8)}));
  EXPECT_EQ(snapshot.info.tree_count, 2);
}

TEST_P(MapStoreTest, FailedWritesLeaveTheMapExactlyAsItWas) {
  store_.CreateMap("m", "", "");
  store_.WriteTrees("m", {Tree(1, 0, 0), Tree(7, 1, 1)}, WriteMode::kAppend);
  const MapSnapshot before = store_.ReadMap("m");

  // A large batch whose only conflict is its last tree: all earlier rows must be undone.
  std::vector<TreeRecord> late_conflict;
  for (int64_t id = 100; id < 5100; ++id) late_conflict.push_back(Tree(id, 2, 3));
  late_conflict.push_back(Tree(7, 9, 9));
  ExpectError([&] { store_.WriteTrees("m", late_conflict, WriteMode::kAppend); },
              Code::kInvalidArgument, "index 5000 (id 7): tree id already exists in the map");

  ExpectError(
      [&] {
        store_.WriteTrees("m", {Tree(3, 0, 0), Tree(4, 0, 0), Tree(3, 1, 1)}, WriteMode::kAppend);
      },
      Code::kInvalidArgument, "duplicate tree id 3 at indices 0 and 2");
  ExpectError(
      [&] {
        store_.WriteTrees("m", {Tree(3, 0, 0), Tree(3, 1, 1)}, WriteMode::kReplace);
      },
      Code::kInvalidArgument, "duplicate tree id 3");

  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  ExpectError(
      [&] {
        store_.WriteTrees("m", {Tree(20, 0, 0), Tree(21, nan, 0)}, WriteMode::kAppend);
      },
      Code::kInvalidArgument, "tree at index 1 (id 21): x must be a finite number");
  ExpectError([&] { store_.WriteTrees("m", {Tree(std::nullopt, 0, -inf)}, WriteMode::kReplace); },
              Code::kInvalidArgument, "tree at index 0: y must be a finite number");
  TreeRecord bad_z = Tree(22, 0, 0);
  bad_z.z = nan;
  ExpectError([&] { store_.WriteTrees("m", {bad_z}, WriteMode::kReplace); }, Code::kInvalidArgument,
              "z must be a finite number");
  TreeRecord bad_dbh = Tree(23, 0, 0);
  bad_dbh.dbh = inf;
  ExpectError([&] { store_.WriteTrees("m", {bad_dbh}, WriteMode::kAppend); },
              Code::kInvalidArgument, "dbh must be a finite number");
  TreeRecord bad_text = Tree(24, 0, 0);
  bad_text.attributes["species"] = "\xff\xfe";
  ExpectError(
      [&] {
        store_.WriteTrees("m", {Tree(25, 0, 0), bad_text}, WriteMode::kReplace);
      },
      Code::kInvalidArgument, "index 1 (id 24): attributes are not valid UTF-8");

  const MapSnapshot after = store_.ReadMap("m");
  EXPECT_EQ(after.trees, before.trees);
  EXPECT_EQ(after.info.version, before.info.version);
  EXPECT_EQ(after.info.tree_count, before.info.tree_count);
  EXPECT_EQ(after.info.extent->max_x, before.info.extent->max_x);
  EXPECT_EQ(store_.TreesInBox("m", Extent{-10, -10, 10, 10}).size(), 2u);  // index unchanged
}

TEST_P(MapStoreTest, MissingIdsGetTheNextFreeIdsInOrder) {
  store_.CreateMap("m", "", "");
  const std::nullopt_t none = std::nullopt;
  store_.WriteTrees("m", {Tree(none, 0, 0), Tree(10, 1, 0), Tree(none, 2, 0)}, WriteMode::kAppend);
  MapSnapshot snapshot = store_.ReadMap("m");
  EXPECT_EQ(Ids(snapshot.trees), (std::vector<int64_t>{10, 11, 12}));
  EXPECT_EQ(snapshot.trees[1].x, 0);  // the first tree without an id got 11
  EXPECT_EQ(snapshot.trees[2].x, 2);

  store_.WriteTrees("m", {Tree(5, 3, 0), Tree(none, 4, 0)}, WriteMode::kAppend);  // above map's 12
  EXPECT_EQ(Ids(store_.ReadMap("m").trees), (std::vector<int64_t>{5, 10, 11, 12, 13}));

  // Replace forgets the old ids; fresh ids start at 1 and stay above the batch's own ids.
  store_.WriteTrees("m", {Tree(none, 0, 0), Tree(none, 0, 0)}, WriteMode::kReplace);
  EXPECT_EQ(Ids(store_.ReadMap("m").trees), (std::vector<int64_t>{1, 2}));
  store_.WriteTrees("m", {Tree(-5, 0, 0), Tree(none, 0, 0)}, WriteMode::kReplace);
  EXPECT_EQ(Ids(store_.ReadMap("m").trees), (std::vector<int64_t>{-5, 1}));

  const int64_t kMax = std::numeric_limits<int64_t>::max();
  store_.WriteTrees("m", {Tree(kMax - 2, 0, 0), Tree(none, 0, 0), Tree(none, 0, 0)},
                    WriteMode::kReplace);  // the last free ids, up to the largest int64
  EXPECT_EQ(Ids(store_.ReadMap("m").trees), (std::vector<int64_t>{kMax - 2, kMax - 1, kMax}));
  store_.WriteTrees("m", {Tree(kMax, 0, 0)}, WriteMode::kReplace);
  ExpectError([&] { store_.WriteTrees("m", {Tree(none, 0, 0)}, WriteMode::kAppend); },
              Code::kInvalidArgument, "no free tree ids");
  EXPECT_EQ(Ids(store_.ReadMap("m").trees), (std::vector<int64_t>{kMax}));
}

TEST_P(MapStoreTest, ValuesRoundTripBitForBit) {
  std::mt19937_64 rng(42);
  std::uniform_int_distribution<uint64_t> bits;
  // Finite doubles from random bit patterns (all exponents), plus hand-picked edge cases.
  auto random_double = [&] {
    while (true) {
      const double value = std::bit_cast<double>(bits(rng));
      if (std::isfinite(value)) return value;
    }
  };
  std::vector<double> specials = {0.0,
                                  1.0,
                                  3.0,
                                  1e300,
                                  -1e300,
                                  4.9e-324,
                                  2.2250738585072014e-308,
                                  9007199254740993.0,
                                  0.1,
                                  1e15 + 0.5,
                                  -123456789.0};
  std::vector<TreeRecord> trees;
  for (int i = 0; i < 2000; ++i) {
    TreeRecord tree;
    tree.id = i;
    tree.x = i < static_cast<int>(specials.size()) ? specials[i] : random_double();
    tree.y = random_double();
    if (i % 3 != 0) tree.z = random_double();
    if (i % 4 != 0) tree.dbh = random_double();
    if (i % 5 == 1) {
      tree.attributes = {{"species", "Picea abies"},
                         {"note", "quote \" backslash \\ tab \t"},
                         {"", "empty key"},
                         {"empty", ""},
                         {"utf8", "\xc3\xa4\xe2\x82\xac"},
                         {"number", "12.5"}};
    }
    if (i % 5 == 2) tree.null_attributes = {"LI", "species"};  // unknown survey columns
    if (i % 5 == 3) {
      tree.attributes = {{"species", "Pinus"}};
      tree.null_attributes = {"LO"};
    }
    trees.push_back(tree);
  }
  store_.CreateMap("m", "", "");
  store_.WriteTrees("m", trees, WriteMode::kReplace);
  const MapSnapshot snapshot = store_.ReadMap("m");
  ASSERT_EQ(snapshot.trees.size(), trees.size());
  auto same_bits = [](std::optional<double> a, std::optional<double> b) {
    return a.has_value() == b.has_value() &&
           (!a || std::bit_cast<uint64_t>(*a) == std::bit_cast<uint64_t>(*b));
  };
  for (size_t i = 0; i < trees.size(); ++i) {
    const TreeRecord& in = trees[i];
    const TreeRecord& out = snapshot.trees[i];
    EXPECT_EQ(out.id, in.id);
    EXPECT_TRUE(same_bits(out.x, in.x)) << "tree " << i;
    EXPECT_TRUE(same_bits(out.y, in.y)) << "tree " << i;
    EXPECT_TRUE(same_bits(out.z, in.z)) << "tree " << i;
    EXPECT_TRUE(same_bits(out.dbh, in.dbh)) << "tree " << i;
    EXPECT_EQ(out.attributes, in.attributes) << "tree " << i;
    EXPECT_EQ(out.null_attributes, in.null_attributes) << "tree " << i;
  }
  // The documented exception: SQLite's REAL affinity stores -0.0 as integer 0; PostgreSQL
  // keeps the sign.
  store_.WriteTrees("m", {Tree(1, -0.0, 0)}, WriteMode::kReplace);
  const double zero = store_.ReadMap("m").trees[0].x;
  EXPECT_EQ(zero, 0.0);
  EXPECT_EQ(std::signbit(zero), GetParam() == Backend::kPostgres);
}

TEST_P(MapStoreTest, TreesInBoxMatchesBruteForce) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> coordinate(-100.0, 100.0);
  std::vector<TreeRecord> trees;
  for (int64_t id = 1; id <= 3000; ++id)
    trees.push_back(Tree(id, coordinate(rng), coordinate(rng)));
  store_.CreateMap("m", "", "");
  store_.CreateMap("other", "", "");
  store_.WriteTrees("m", trees, WriteMode::kAppend);
  store_.WriteTrees("other", trees, WriteMode::kAppend);  // same places, must not leak in
  // Beyond the float range of the index, each alone in its write (and so in its index block).
  for (const TreeRecord& far : {Tree(5000, 1e300, -1e300), Tree(5001, -1e300, 1e300)}) {
    store_.WriteTrees("m", {far}, WriteMode::kAppend);
    trees.push_back(far);
  }

  std::vector<Extent> boxes;
  for (int i = 0; i < 200; ++i) {
    const double x0 = coordinate(rng), x1 = coordinate(rng) / 8, y0 = coordinate(rng);
    const double y1 = coordinate(rng) / 8;
    boxes.push_back(Extent{std::min(x0, x0 + x1), std::min(y0, y0 + y1), std::max(x0, x0 + x1),
                           std::max(y0, y0 + y1)});
  }
  for (int i = 0; i < 50; ++i) {  // edges exactly on tree coordinates: bounds are inclusive
    const TreeRecord& a = trees[static_cast<size_t>(i)];
    const TreeRecord& b = trees[static_cast<size_t>(i + 1000)];
    boxes.push_back(Extent{a.x, a.y, a.x, a.y});
    boxes.push_back(
        Extent{std::min(a.x, b.x), std::min(a.y, b.y), std::max(a.x, b.x), std::max(a.y, b.y)});
    // Just beside a tree, closer than float32 resolution: must not be returned.
    boxes.push_back(Extent{std::nextafter(a.x, 1e9), a.y, std::nextafter(a.x, 1e9) + 1e-9, a.y});
  }
  const double inf = std::numeric_limits<double>::infinity();
  boxes.push_back(Extent{-inf, -inf, inf, inf});
  boxes.push_back(Extent{-1e301, 1e299, -1e299, 1e301});
  boxes.push_back(Extent{1e299, -1e301, 1e301, -1e299});

  for (const Extent& box : boxes) {
    std::vector<int64_t> expected;
    for (const TreeRecord& tree : trees) {
      if (tree.x >= box.min_x && tree.x <= box.max_x && tree.y >= box.min_y &&
          tree.y <= box.max_y) {
        expected.push_back(*tree.id);
      }
    }
    const std::vector<TreeRecord> found = store_.TreesInBox("m", box);
    ASSERT_EQ(Ids(found), expected) << "box x [" << box.min_x << ", " << box.max_x << "] y ["
                                    << box.min_y << ", " << box.max_y << "]";
  }
  EXPECT_EQ(store_.TreesInBox("m", boxes.back()).size(), 1u);
  EXPECT_EQ(store_.TreesInBox("m", Extent{-inf, -inf, inf, inf}).size(), trees.size());
  const std::vector<TreeRecord> central = store_.TreesInBox("m", Extent{-20, -20, 20, 20});
  EXPECT_GT(central.size(), 50u);
  for (const TreeRecord& tree : central) {  // whole records, not just ids
    EXPECT_EQ(tree, trees[static_cast<size_t>(*tree.id - 1)]);
  }

  const double nan = std::numeric_limits<double>::quiet_NaN();
  ExpectError(
      [&] {
        store_.TreesInBox("m", Extent{nan, 0, 1, 1});
      },
      Code::kInvalidArgument, "invalid box");
  ExpectError(
      [&] {
        store_.TreesInBox("m", Extent{2, 0, 1, 1});
      },
      Code::kInvalidArgument, "invalid box");
}

}  // namespace
}  // namespace forestmap::storage
