// The trees of a map version page by page (server/app/tree_pages.h), as the export stream and the
// web page read them: every tree once, by id, at every page size; a box filters; a version that
// disappears after the first page is ABORTED, not a silent short answer.

#include "server/app/tree_pages.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <vector>

#include "server/app/errors.h"
#include "storage/sqlite/store.h"

namespace forestmap::server {
namespace {

using ::testing::HasSubstr;

constexpr int kTrees = 25;

class TreePagesTest : public ::testing::Test {
 protected:
  TreePagesTest() {
    store_.CreateMap("plot", "", "");
    std::vector<storage::TreeRecord> trees(kTrees);
    for (int i = 0; i < kTrees; ++i) {
      trees[i].id = 100 + i;
      trees[i].x = i;
      trees[i].y = 2.0 * i;
    }
    store_.WriteTrees("plot", trees, storage::WriteMode::kAppend);
  }

  // Every page of `pages`, concatenated; `sizes` gets the size of each page.
  static std::vector<storage::TreeRecord> ReadAll(TreePages& pages, std::vector<size_t>& sizes) {
    std::vector<storage::TreeRecord> all;
    while (!pages.done()) {
      const std::vector<storage::TreeRecord> page = pages.Next();
      sizes.push_back(page.size());
      all.insert(all.end(), page.begin(), page.end());
    }
    return all;
  }

  storage::SqliteMapStore store_{":memory:"};
};

TEST_F(TreePagesTest, EveryTreeOnceInIdOrderAtEveryPageSize) {
  for (const int page_trees : {1, 4, 5, 24, 25, 26, 1000}) {
    TreePages pages(store_, store_.GetMap("plot"), page_trees);
    std::vector<size_t> sizes;
    const std::vector<storage::TreeRecord> all = ReadAll(pages, sizes);
    ASSERT_EQ(all.size(), static_cast<size_t>(kTrees)) << page_trees;
    for (int i = 0; i < kTrees; ++i) EXPECT_EQ(all[i].id, 100 + i) << page_trees;
    // Full pages, then one short (maybe empty) last page.
    for (size_t p = 0; p + 1 < sizes.size(); ++p) EXPECT_EQ(sizes[p], size_t(page_trees));
    EXPECT_LT(sizes.back(), size_t(page_trees));
  }
}

TEST_F(TreePagesTest, ABoxKeepsTheTreesInsideOnly) {
  TreePages pages(store_, store_.GetMap("plot"), 3, storage::Extent{5, 0, 9.5, 100});
  std::vector<size_t> sizes;
  const std::vector<storage::TreeRecord> inside = ReadAll(pages, sizes);
  ASSERT_EQ(inside.size(), 5u);  // x = 5 .. 9
  EXPECT_EQ(inside.front().x, 5);
  EXPECT_EQ(inside.back().x, 9);
}

TEST_F(TreePagesTest, AnOldVersionReadsAsItWas) {
  const storage::MapInfo before = store_.GetMap("plot");
  store_.WriteTrees("plot", {}, storage::WriteMode::kReplace);
  TreePages pages(store_, before, 10);
  std::vector<size_t> sizes;
  EXPECT_EQ(ReadAll(pages, sizes).size(), static_cast<size_t>(kTrees));
}

TEST_F(TreePagesTest, AVersionPrunedAfterTheFirstPageIsAborted) {
  TreePages pages(store_, store_.GetMap("plot"), 10);
  EXPECT_EQ(pages.Next().size(), 10u);
  store_.WriteTrees("plot", {}, storage::WriteMode::kReplace);
  store_.PruneVersions("plot", 1);
  try {
    pages.Next();
    ADD_FAILURE() << "a pruned version read on";
  } catch (const ServiceError& e) {
    EXPECT_EQ(e.code(), ErrorCode::kAborted);
    EXPECT_THAT(e.what(), HasSubstr("was deleted or pruned"));
  }
}

TEST_F(TreePagesTest, AnUnknownMapIsNotFoundOnTheFirstPage) {
  storage::MapInfo missing = store_.GetMap("plot");
  missing.name = "missing";
  TreePages pages(store_, missing, 10);
  try {
    pages.Next();
    ADD_FAILURE() << "no error";
  } catch (const storage::StorageError& e) {
    EXPECT_EQ(e.code(), storage::StorageError::Code::kNotFound);
  }
}

}  // namespace
}  // namespace forestmap::server
