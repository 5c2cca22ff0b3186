// The order of a map's attribute columns on every backend: stored with the upload that gives it
// (the survey file's order, which exports keep), merged on append, replaced on replace, kept by
// an upload without one, versioned, restored, pruned and deleted with the map. And MapInfo's
// has_boundary wherever a map's info is read.
#include <gtest/gtest.h>

#include <optional>
#include <string>
#include <vector>

#include "storage/staged_writes.h"
#include "tests/storage/store_backends.h"
#include "tests/storage/store_test_util.h"

namespace forestmap::storage {
namespace {

using Names = std::vector<std::string>;

TreeRecord Surveyed(int64_t id, const std::vector<std::string>& columns) {
  TreeRecord tree = Tree(id, static_cast<double>(id), 1);
  for (const std::string& name : columns) tree.attributes[name] = name + "-" + std::to_string(id);
  return tree;
}

MapInfo UploadWithColumns(MapStore& store, const std::string& name,
                          const std::vector<TreeRecord>& trees, const Names& columns,
                          WriteMode mode = WriteMode::kAppend, bool create = false,
                          std::optional<Boundary> boundary = std::nullopt) {
  UploadPlan plan;
  plan.mode = mode;
  plan.create_map = create;
  plan.attribute_columns = columns;
  plan.boundary = std::move(boundary);
  auto upload = store.BeginUpload(name, plan);
  upload->Append(trees);
  return upload->Commit();
}

Boundary TriangleBoundary() {
  BoundaryPolygon polygon;
  polygon.outer = {{0, 0}, {50, 0}, {0, 50}};
  return {polygon};
}

class ColumnOrderTest : public ::testing::TestWithParam<Backend> {
 protected:
  TestStore test_store_{GetParam()};
  MapStore& store_ = *test_store_;
};
INSTANTIATE_TEST_SUITE_P(Backends, ColumnOrderTest, kAllBackends, BackendName);

const Names kCrew = {"species", "height", "crown", "plot_id"};

TEST_P(ColumnOrderTest, AnUploadStoresTheFilesOrder) {
  const MapInfo info =
      UploadWithColumns(store_, "m", {Surveyed(1, kCrew)}, kCrew, WriteMode::kAppend, true);
  EXPECT_EQ(store_.ReadMap("m").attribute_columns, kCrew);
  EXPECT_EQ(store_.ReadMapVersion("m", info.version).attribute_columns, kCrew);
  EXPECT_EQ(store_.ReadAttributeColumns("m", 0), kCrew);
  EXPECT_EQ(store_.ReadAttributeColumns("m", info.version), kCrew);
}

TEST_P(ColumnOrderTest, AMapWrittenWithoutOneHasNone) {
  store_.CreateMap("m", "", "");
  store_.WriteTrees("m", {Surveyed(1, kCrew)}, WriteMode::kAppend);
  EXPECT_TRUE(store_.ReadMap("m").attribute_columns.empty());
  EXPECT_TRUE(store_.ReadAttributeColumns("m", 0).empty());
}

TEST_P(ColumnOrderTest, AppendAddsNewNamesReplaceSetsItAndVersionsKeepTheirOwn) {
  store_.CreateMap("m", "", "");  // 1
  EXPECT_EQ(UploadWithColumns(store_, "m", {Surveyed(1, kCrew)}, kCrew).version,
            2);  // the crew's order
  // An append: the map's order, then the file's new names in the file's order.
  EXPECT_EQ(UploadWithColumns(store_, "m", {Surveyed(2, {"zeta", "notes", "species"})},
                              {"zeta", "notes", "species"})
                .version,
            3);
  const Names appended = {"species", "height", "crown", "plot_id", "zeta", "notes"};
  EXPECT_EQ(store_.ReadMap("m").attribute_columns, appended);
  // An upload without an order keeps the map's; an order alone makes no version.
  EXPECT_EQ(UploadWithColumns(store_, "m", {Surveyed(3, {"alpha"})}, {}).version, 4);
  EXPECT_EQ(store_.ReadMap("m").attribute_columns, appended);
  EXPECT_EQ(UploadWithColumns(store_, "m", {}, {"other"}).version, 4);
  EXPECT_EQ(store_.ReadMap("m").attribute_columns, appended);
  // A replace: the file's order alone.
  EXPECT_EQ(
      UploadWithColumns(store_, "m", {Surveyed(9, {"b", "a"})}, {"b", "a"}, WriteMode::kReplace)
          .version,
      5);
  EXPECT_EQ(store_.ReadMap("m").attribute_columns, (Names{"b", "a"}));
  // Merges and other writes leave it.
  store_.WriteTrees("m", {Surveyed(10, {"c"})}, WriteMode::kAppend);  // 6
  EXPECT_EQ(store_.ReadMap("m").attribute_columns, (Names{"b", "a"}));

  EXPECT_TRUE(store_.ReadMapVersion("m", 1).attribute_columns.empty());
  EXPECT_EQ(store_.ReadMapVersion("m", 2).attribute_columns, kCrew);
  EXPECT_EQ(store_.ReadAttributeColumns("m", 3), appended);
  EXPECT_EQ(store_.ReadMapVersion("m", 4).attribute_columns, appended);
  EXPECT_EQ(store_.ReadAttributeColumns("m", 5), (Names{"b", "a"}));
  ExpectError([&] { store_.ReadAttributeColumns("m", 99); }, StorageError::Code::kNotFound, "");
}

TEST_P(ColumnOrderTest, RestorePruneAndDeleteFollowTheVersions) {
  store_.CreateMap("m", "", "");                                                               // 1
  UploadWithColumns(store_, "m", {Surveyed(1, kCrew)}, kCrew);                                 // 2
  UploadWithColumns(store_, "m", {Surveyed(2, {"b", "a"})}, {"b", "a"}, WriteMode::kReplace);  // 3
  UploadWithColumns(store_, "m", {Surveyed(3, {"b"})}, {});                                    // 4
  EXPECT_EQ(store_.RestoreVersion("m", 2).version, 5);
  EXPECT_EQ(store_.ReadMap("m").attribute_columns, kCrew);
  EXPECT_EQ(store_.ReadAttributeColumns("m", 4), (Names{"b", "a"}));
  // Keeping versions 4..5: version 4 still reads the order set at version 3.
  store_.PruneVersions("m", 2);
  EXPECT_EQ(store_.ReadAttributeColumns("m", 4), (Names{"b", "a"}));
  EXPECT_EQ(store_.ReadAttributeColumns("m", 5), kCrew);
  if (GetParam() != Backend::kSqlite) {
    EXPECT_EQ(test_store_.Column("SELECT version FROM map_columns ORDER BY version"),
              (std::vector<std::string>{"3", "5"}));
  }
  store_.DeleteMap("m");
  store_.CreateMap("m", "", "");
  EXPECT_TRUE(store_.ReadMap("m").attribute_columns.empty());
}

TEST_P(ColumnOrderTest, MapInfoSaysWhetherTheMapHasABoundary) {
  EXPECT_FALSE(store_.CreateMap("m", "", "").has_boundary);
  EXPECT_FALSE(store_.GetMap("m").has_boundary);
  EXPECT_TRUE(UploadWithColumns(store_, "m", {}, {}, WriteMode::kAppend, false, TriangleBoundary())
                  .has_boundary);  // 2
  EXPECT_TRUE(store_.GetMap("m").has_boundary);
  EXPECT_TRUE(store_.ListMaps().at(0).has_boundary);
  EXPECT_TRUE(store_.ReadMap("m").info.has_boundary);
  store_.WriteTrees("m", {Surveyed(1, {})}, WriteMode::kAppend);  // 3: other writes keep it
  EXPECT_TRUE(store_.GetMap("m").has_boundary);
  EXPECT_FALSE(store_.ReadMapVersion("m", 1).info.has_boundary);
  EXPECT_TRUE(store_.ReadMapVersion("m", 2).info.has_boundary);
  EXPECT_FALSE(
      UploadWithColumns(store_, "m", {}, {}, WriteMode::kAppend, false, Boundary{}).has_boundary);
  EXPECT_FALSE(store_.GetMap("m").has_boundary);
  EXPECT_TRUE(store_.RestoreVersion("m", 3).has_boundary);
  EXPECT_TRUE(store_.GetMap("m").has_boundary);
  store_.CreateMap("other", "", "");
  EXPECT_FALSE(store_.GetMap("other").has_boundary);
}

}  // namespace
}  // namespace forestmap::storage
