// Exactly-once writes without a transport (server/app/exactly_once.h): a request id applies its
// write once and answers every repeat with the first answer; an id is never answered for another
// call; a write past its deadline commits nothing.

#include "server/app/exactly_once.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <string>

#include "storage/sqlite/store.h"

namespace forestmap::server {
namespace {

using ::testing::HasSubstr;

class ExactlyOnceTest : public ::testing::Test {
 protected:
  // Creates map `name` under `call`; the stored answer is "created <name> v<version>". Returns
  // what WriteExactlyOnce returned, and counts the writes that ran.
  std::optional<std::string> Create(const WriteCall& call, const std::string& name) {
    return WriteExactlyOnce(
        store_, call,
        [](const storage::MapInfo& info) {
          return "created " + info.name + " v" + std::to_string(info.version);
        },
        [&] {
          ++writes_;
          store_.CreateMap(name, "", "");
        });
  }

  storage::SqliteMapStore store_{":memory:"};
  int writes_ = 0;
};

TEST_F(ExactlyOnceTest, ARepeatedIdGetsTheFirstAnswerWithoutWritingAgain) {
  const WriteCall call{"create-a-1", "CreateMap"};
  EXPECT_FALSE(Create(call, "a").has_value());  // written now
  EXPECT_EQ(writes_, 1);
  const std::optional<std::string> again = Create(call, "a");
  ASSERT_TRUE(again.has_value());
  EXPECT_EQ(*again, "created a v1");
  EXPECT_EQ(writes_, 1);
  EXPECT_EQ(StoredAnswer(store_, "create-a-1", "CreateMap"), "created a v1");
}

TEST_F(ExactlyOnceTest, WithoutAnIdEveryCallWritesAndNothingIsStored) {
  EXPECT_FALSE(Create(WriteCall{"", "CreateMap"}, "a").has_value());
  EXPECT_THROW(Create(WriteCall{"", "CreateMap"}, "a"), storage::StorageError);  // exists
  EXPECT_EQ(writes_, 2);
}

TEST_F(ExactlyOnceTest, AnIdIsNeverAnsweredForAnotherCall) {
  EXPECT_FALSE(Create(WriteCall{"id-1", "CreateMap"}, "a").has_value());
  try {
    Create(WriteCall{"id-1", "DeleteMap"}, "b");
    ADD_FAILURE() << "id reused for another call";
  } catch (const ValidationError& e) {
    EXPECT_THAT(e.what(), HasSubstr("already used for a CreateMap call"));
  }
  EXPECT_EQ(writes_, 1);
}

TEST_F(ExactlyOnceTest, MalformedIdsAreRefusedBeforeAnyWrite) {
  EXPECT_THROW(Create(WriteCall{"has space", "CreateMap"}, "a"), ValidationError);
  EXPECT_THROW(Create(WriteCall{std::string(kMaxRequestIdLength + 1, 'x'), "CreateMap"}, "a"),
               ValidationError);
  EXPECT_NO_THROW(ValidateRequestId(std::string(kMaxRequestIdLength, 'x')));
  EXPECT_EQ(writes_, 0);
  EXPECT_TRUE(store_.ListMaps().empty());
}

TEST_F(ExactlyOnceTest, AWritePastItsDeadlineCommitsNothing) {
  WriteCall call{"late-1", "CreateMap"};
  call.deadline = std::chrono::system_clock::now() - std::chrono::seconds(1);
  try {
    Create(call, "a");
    ADD_FAILURE() << "a late write committed";
  } catch (const storage::StorageError& e) {
    EXPECT_EQ(e.code(), storage::StorageError::Code::kDeadlineExceeded);
  }
  EXPECT_TRUE(store_.ListMaps().empty());
  EXPECT_FALSE(StoredAnswer(store_, "late-1", "CreateMap").has_value());
}

}  // namespace
}  // namespace forestmap::server
