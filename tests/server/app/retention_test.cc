// History retention (server/app/retention.h), the one implementation every transport calls: the
// --keep-versions policy after a write, and PruneVersions on demand. A failure of the store after
// a committed write is reported with its cause, never swallowed, and the write stands.

#include "server/app/retention.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "storage/sqlite/store.h"
#include "tests/server/gated_store.h"

namespace forestmap::server {
namespace {

using ::testing::HasSubstr;

class RetentionPolicyTest : public ::testing::Test {
 protected:
  // A map with `writes` uploads after its creation: versions 1 .. writes + 1.
  void MakeMap(const std::string& name, int writes) {
    store_.CreateMap(name, "", "");
    for (int i = 0; i < writes; ++i) {
      std::vector<storage::TreeRecord> trees(1);
      trees[0].x = i;
      store_.WriteTrees(name, trees, storage::WriteMode::kAppend);
    }
  }
  size_t Versions(const std::string& name) { return store_.ListVersions(name, 0).size(); }
  FaultReport Report() {
    return [this](std::string_view message) { reports_.emplace_back(message); };
  }

  storage::SqliteMapStore store_{":memory:"};
  GatedStore gated_{store_};
  std::vector<std::string> reports_;
};

TEST_F(RetentionPolicyTest, PolicyKeepsTheNewestVersionsAfterAWrite) {
  MakeMap("plot", 5);
  const RetentionPolicy policy(store_, 3, Report());
  EXPECT_TRUE(policy.AfterWrite("plot"));
  const std::vector<storage::VersionRecord> kept = store_.ListVersions("plot", 0);
  ASSERT_EQ(kept.size(), 3u);
  EXPECT_EQ(store_.GetMap("plot").version, 6);
  EXPECT_EQ(store_.GetMap("plot").tree_count, 5);  // the current version is untouched
  EXPECT_TRUE(reports_.empty());
}

TEST_F(RetentionPolicyTest, PolicyOfZeroKeepsEveryVersion) {
  MakeMap("plot", 5);
  const RetentionPolicy policy(gated_, 0, Report());
  int prunes = 0;
  gated_.before_prune = [&] { ++prunes; };
  EXPECT_TRUE(policy.AfterWrite("plot"));
  EXPECT_EQ(prunes, 0);
  EXPECT_EQ(Versions("plot"), 6u);
}

TEST_F(RetentionPolicyTest, AStoreFailureIsReportedWithItsCauseAndTheWriteStands) {
  MakeMap("plot", 4);
  const RetentionPolicy policy(gated_, 2, Report());
  gated_.before_prune = [] {
    throw storage::StorageError(storage::StorageError::Code::kFull, "disk full (injected)");
  };
  EXPECT_FALSE(policy.AfterWrite("plot"));
  ASSERT_EQ(reports_.size(), 1u);
  EXPECT_THAT(reports_[0], HasSubstr("retention of map \"plot\" failed (the write stands)"));
  EXPECT_THAT(reports_[0], HasSubstr("disk full (injected)"));
  EXPECT_EQ(Versions("plot"), 5u);  // nothing pruned, the written version is there
  EXPECT_EQ(store_.GetMap("plot").version, 5);
}

TEST_F(RetentionPolicyTest, EvenAnExceptionOfNoKnownTypeIsReported) {
  MakeMap("plot", 2);
  const RetentionPolicy policy(gated_, 1, Report());
  gated_.before_prune = [] { throw 42; };
  EXPECT_FALSE(policy.AfterWrite("plot"));
  ASSERT_EQ(reports_.size(), 1u);
  EXPECT_THAT(reports_[0], HasSubstr("retention of map \"plot\" failed"));
}

TEST_F(RetentionPolicyTest, AnUnknownMapIsReportedNotThrown) {
  const RetentionPolicy policy(store_, 2, Report());
  EXPECT_FALSE(policy.AfterWrite("missing"));
  ASSERT_EQ(reports_.size(), 1u);
  EXPECT_THAT(reports_[0], HasSubstr("\"missing\""));
}

TEST_F(RetentionPolicyTest, PruneHistoryKeepsAtLeastTheCurrentVersion) {
  MakeMap("plot", 3);
  try {
    PruneHistory(store_, "plot", 0);
    ADD_FAILURE() << "keep 0 accepted";
  } catch (const ValidationError& e) {
    EXPECT_THAT(e.what(), HasSubstr("keep is 0"));
  }
  EXPECT_EQ(Versions("plot"), 4u);
  const storage::PruneResult pruned = PruneHistory(store_, "plot", 1);
  EXPECT_EQ(pruned.versions_removed, 3);
  EXPECT_EQ(pruned.info.version, 4);
  EXPECT_EQ(Versions("plot"), 1u);
  EXPECT_EQ(store_.GetMap("plot").tree_count, 3);
}

TEST_F(RetentionPolicyTest, NonsenseOptionsAreRefused) {
  EXPECT_THROW(RetentionPolicy(store_, -1, Report()), std::invalid_argument);
  EXPECT_THROW(RetentionPolicy(store_, 1, FaultReport()), std::invalid_argument);
}

}  // namespace
}  // namespace forestmap::server
