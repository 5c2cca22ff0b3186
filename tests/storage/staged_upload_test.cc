// Uploads staged in the database and exports read page by page on every backend
// (bounded memory; storage/staged_writes.h): a create with trees is atomic, ids are checked, other
// maps are written meanwhile, attributes survive the staging, pages add up to their version.

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "storage/staged_writes.h"
#include "tests/storage/store_backends.h"
#include "tests/storage/store_test_util.h"

namespace forestmap::storage {
namespace {

using Code = StorageError::Code;

class StagedUploadBackendTest : public ::testing::TestWithParam<Backend> {};

TEST_P(StagedUploadBackendTest, CreateIsAtomicIdsAreCheckedAndOtherMapsGoOn) {
  TestStore test_store(GetParam());
  MapStore& store = *test_store;
  UploadPlan create;
  create.create_map = true;
  create.crs = "EPSG:2959";
  {
    auto upload = store.BeginUpload("a", create);
    upload->Append(Grid(2000, 1));
    store.CreateMap("b", "", "");  // another map is written meanwhile
    store.WriteTrees("b", Grid(5), WriteMode::kAppend);
    EXPECT_EQ(CodeOf([&] { store.GetMap("a"); }), Code::kNotFound);
  }  // never committed
  EXPECT_EQ(CodeOf([&] { store.GetMap("a"); }), Code::kNotFound);
  EXPECT_EQ(store.GetMap("b").tree_count, 5);

  auto upload = store.BeginUpload("a", create);
  upload->Append(Grid(10, 100));
  try {
    upload->Append(Grid(10, 105));
    FAIL() << "no error";
  } catch (const StorageError& e) {
    EXPECT_EQ(e.code(), Code::kInvalidArgument);
    EXPECT_NE(std::string(e.what()).find("trees[10].id 105 duplicates trees[5].id"),
              std::string::npos)
        << e.what();
  }
  upload = store.BeginUpload("a", create);
  upload->Append(Grid(10, 100));
  upload->Append(Grid(5));  // ids 110..114
  const MapInfo info = upload->Commit();
  EXPECT_EQ(info.tree_count, 15);
  EXPECT_EQ(info.version, 2);
  EXPECT_EQ(store.GetMap("a").crs, "EPSG:2959");
  EXPECT_EQ(*store.ReadMap("a").trees.back().id, 114);
  EXPECT_EQ(CodeOf([&] { store.BeginUpload("a", create); }), Code::kAlreadyExists);

  auto clash = store.BeginUpload("a", UploadPlan{});
  clash->Append(Grid(2, 113));
  EXPECT_EQ(CodeOf([&] { clash->Commit(); }), Code::kInvalidArgument);
  EXPECT_EQ(store.GetMap("a").version, 2);
  EXPECT_EQ(store.ReadMap("a").trees.size(), 15u);
}

// A staged upload keeps attributes and the columns a tree has no value for (null), like a
// direct write does: the PostgreSQL staging path once encoded attributes without the nulls.
TEST_P(StagedUploadBackendTest, AttributesAndNullColumnsSurviveTheStaging) {
  TestStore test_store(GetParam());
  MapStore& store = *test_store;
  std::vector<TreeRecord> trees = Grid(3, 1);
  trees[0].attributes = {{"Spp", "41"}};
  trees[0].null_attributes = {"LI"};
  UploadPlan create;
  create.create_map = true;
  auto upload = store.BeginUpload("a", create);
  upload->Append(trees);
  upload->Commit();
  const MapSnapshot snapshot = store.ReadMap("a");
  ASSERT_EQ(snapshot.trees.size(), 3u);
  const TreeRecord& first = snapshot.trees.front();
  EXPECT_EQ(first.attributes, trees[0].attributes);
  EXPECT_EQ(first.null_attributes, trees[0].null_attributes);
}

INSTANTIATE_TEST_SUITE_P(Backends, StagedUploadBackendTest, kAllBackends, BackendName);

// ---- Pages, on both backends ----

class TreePagesTest : public ::testing::TestWithParam<Backend> {};

std::vector<TreeRecord> AllPages(MapStore& store, const std::string& name, TreePageQuery query) {
  std::vector<TreeRecord> trees;
  while (true) {
    const std::vector<TreeRecord> page = store.ReadTreesPage(name, query);
    trees.insert(trees.end(), page.begin(), page.end());
    if (static_cast<int64_t>(page.size()) < query.limit) return trees;
    query.after_id = page.back().id;
  }
}

TEST_P(TreePagesTest, PagesOfAVersionAddUpToTheVersion) {
  TestStore test_store(GetParam());
  MapStore& store = *test_store;
  const MapInfo created = store.CreateMap("a", "", "");
  store.WriteTrees("a", Grid(1000, 1), WriteMode::kAppend);  // version 2
  std::vector<TreeRecord> changed = Grid(300, 200);
  for (TreeRecord& tree : changed) tree.x += 0.5;
  store.WriteTrees("a", changed, WriteMode::kReplace);  // version 3
  TreePageQuery query;
  query.limit = 64;
  query.created_unix_ms = created.created_unix_ms;
  for (const int64_t version : {2, 3}) {
    query.version = version;
    EXPECT_EQ(AllPages(store, "a", query), store.ReadMapVersion("a", version).trees) << version;
  }
  query.version = 2;
  query.box = Extent{10, 2, 20, 5};
  std::vector<TreeRecord> inside;
  for (const TreeRecord& tree : store.ReadMapVersion("a", 2).trees) {
    if (tree.x >= 10 && tree.x <= 20 && tree.y >= 2 && tree.y <= 5) inside.push_back(tree);
  }
  EXPECT_EQ(AllPages(store, "a", query), inside);

  store.PruneVersions("a", 1);  // version 2 is gone
  query.box.reset();
  EXPECT_EQ(CodeOf([&] { store.ReadTreesPage("a", query); }), Code::kNotFound);
  store.DeleteMap("a");
  store.CreateMap("a", "", "");
  query.version = 1;
  query.created_unix_ms = created.created_unix_ms - 1;  // another map of the same name
  EXPECT_EQ(CodeOf([&] { store.ReadTreesPage("a", query); }), Code::kConflict);
}

INSTANTIATE_TEST_SUITE_P(Backends, TreePagesTest, kAllBackends, BackendName);

}  // namespace
}  // namespace forestmap::storage
