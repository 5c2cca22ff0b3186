// Faults of the database once answered INTERNAL "see server log". Every fault code
// of storage/ maps to its own status (server/grpc/status.cc) with a message naming the cause and
// nothing of the server's paths or SQL, which go to the log only.

#include <gtest/gtest.h>

#include <string>

#include "server/grpc/status.h"
#include "storage/map_store.h"

namespace forestmap::server {
namespace {

using Code = storage::StorageError::Code;

grpc::Status StatusOf(Code code) {
  try {
    throw storage::StorageError(
        code, "step 'INSERT INTO trees ...': details (database '/srv/forestmap/maps.db')");
  } catch (...) {
    return StatusFromCurrentException("UploadTrees");
  }
}

TEST(FaultStatusTest, EachDatabaseFaultHasItsStatusAndCause) {
  struct Case {
    Code code;
    grpc::StatusCode status;
    const char* cause;
  };
  for (const Case& c :
       {Case{Code::kFull, grpc::StatusCode::RESOURCE_EXHAUSTED, "database full"},
        Case{Code::kReadOnly, grpc::StatusCode::FAILED_PRECONDITION, "database read-only"},
        Case{Code::kCorrupt, grpc::StatusCode::DATA_LOSS, "database corrupt"},
        Case{Code::kUnavailable, grpc::StatusCode::UNAVAILABLE, "database unavailable"}}) {
    const grpc::Status status = StatusOf(c.code);
    EXPECT_EQ(status.error_code(), c.status) << c.cause;
    EXPECT_TRUE(status.error_message().starts_with(c.cause)) << status.error_message();
    EXPECT_EQ(status.error_message().find("/srv/forestmap"), std::string::npos);
    EXPECT_EQ(status.error_message().find("INSERT"), std::string::npos);
  }
  EXPECT_EQ(StatusOf(Code::kInternal).error_code(), grpc::StatusCode::INTERNAL);
  EXPECT_EQ(StatusOf(Code::kInternal).error_message(), kInternalErrorMessage);
}

}  // namespace
}  // namespace forestmap::server
