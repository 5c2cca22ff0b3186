// Exactly-once writes in the store (storage/write_request.h): the answer is stored with the write
// in one transaction, a repeated id is refused without writing, a passed deadline commits nothing.
// On every backend.

#include <gtest/gtest.h>

#include <chrono>

#include "tests/storage/store_backends.h"

namespace forestmap::storage {
namespace {

std::vector<TreeRecord> Trees(int count) {
  std::vector<TreeRecord> trees(count);
  for (int i = 0; i < count; ++i) trees[i].x = 3.0 * i;
  return trees;
}

WriteRequest Request(const std::string& id) {
  WriteRequest request;
  request.id = id;
  request.rpc = "UploadTrees";
  request.encode = [](const MapInfo& info) { return "version " + std::to_string(info.version); };
  return request;
}

class WriteRequestTest : public ::testing::TestWithParam<Backend> {};
INSTANTIATE_TEST_SUITE_P(Backends, WriteRequestTest, kAllBackends, BackendName);

TEST_P(WriteRequestTest, AnswerIsStoredWithTheWriteAndAnIdIsAppliedOnce) {
  TestStore test_store(GetParam());
  MapStore& store = *test_store;
  store.CreateMap("plot", "", "");
  EXPECT_FALSE(store.FindRequest("a").has_value());
  {
    const WriteRequest request = Request("a");
    const WriteRequestScope scope(request);
    EXPECT_EQ(store.WriteTrees("plot", Trees(3), WriteMode::kAppend).version, 2);
  }
  const std::optional<StoredRequest> stored = store.FindRequest("a");
  ASSERT_TRUE(stored.has_value());
  EXPECT_EQ(stored->rpc, "UploadTrees");
  EXPECT_EQ(stored->response, "version 2");
  {
    const WriteRequest request = Request("a");
    const WriteRequestScope scope(request);
    try {
      store.WriteTrees("plot", Trees(3), WriteMode::kReplace);
      ADD_FAILURE() << "a repeated id was written again";
    } catch (const StorageError& e) {
      EXPECT_EQ(e.code(), StorageError::Code::kConflict) << e.what();
    }
  }
  EXPECT_EQ(store.GetMap("plot").version, 2);  // the repeat changed nothing
  EXPECT_EQ(CurrentWriteRequest(), nullptr);   // scopes end
}

TEST_P(WriteRequestTest, PassedDeadlineCommitsNothing) {
  TestStore test_store(GetParam());
  MapStore& store = *test_store;
  store.CreateMap("plot", "", "");
  WriteRequest request = Request("late");
  request.deadline = std::chrono::system_clock::now() - std::chrono::milliseconds(1);
  const WriteRequestScope scope(request);
  try {
    store.WriteTrees("plot", Trees(3), WriteMode::kAppend);
    ADD_FAILURE() << "committed after the deadline";
  } catch (const StorageError& e) {
    EXPECT_EQ(e.code(), StorageError::Code::kDeadlineExceeded) << e.what();
  }
  EXPECT_EQ(store.GetMap("plot").version, 1);
  EXPECT_EQ(store.GetMap("plot").tree_count, 0);
  EXPECT_FALSE(store.FindRequest("late").has_value());
  EXPECT_THROW(store.CreateMap("other", "", ""), StorageError);
  EXPECT_EQ(store.ListMaps().size(), 1u);
}

}  // namespace
}  // namespace forestmap::storage
