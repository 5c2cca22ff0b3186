#pragma once
// Pieces the in-process gRPC server tests share: call contexts with a deadline, a fresh
// temporary folder per test, and the first message of an upload stream.

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <string>

#include "forestmap/v1/maps.pb.h"

namespace forestmap::test {

// The header of an upload to `map` (the stream's first message; chunks of trees follow).
inline v1::UploadTreesRequest UploadHeader(const std::string& map, bool replace = false,
                                           bool create_map = false) {
  v1::UploadTreesRequest message;
  message.mutable_header()->set_name(map);
  message.mutable_header()->set_replace(replace);
  message.mutable_header()->set_create_map(create_map);
  return message;
}

// A client context whose deadline, `timeout` from now, turns a hang into a failure.
inline std::unique_ptr<grpc::ClientContext> CallContext(std::chrono::seconds timeout) {
  auto context = std::make_unique<grpc::ClientContext>();
  context->set_deadline(std::chrono::system_clock::now() + timeout);
  return context;
}

// An empty folder in the temporary directory named `prefix` + pid + the running test's name.
inline std::filesystem::path FreshTestDir(const std::string& prefix) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() /
      (prefix + std::to_string(getpid()) + "_" +
       ::testing::UnitTest::GetInstance()->current_test_info()->name());
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace forestmap::test
