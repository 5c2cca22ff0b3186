#pragma once
// Helpers shared by the scan I/O tests: a per-test temporary directory and file writers.

#include <gtest/gtest.h>

#include <exception>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

#include "client/io/scan_io.h"

namespace forestmap::client::testing_util {

// A fresh directory per test, removed afterwards.
class ScanDirTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = std::filesystem::temp_directory_path() /
           (std::string("forestmap_scan_io_") + info->test_suite_name() + "_" + info->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::string Path(const std::string& name) const { return (dir_ / name).string(); }

  std::string Write(const std::string& name, std::string_view bytes) const {
    const std::string path = Path(name);
    std::ofstream out(path, std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return path;
  }

  std::filesystem::path dir_;
};

// A point of `cloud` in the cloud's frame (its origin added back).
inline Eigen::Vector3d Absolute(const algorithms::PointCloud& cloud, size_t i) {
  return cloud.origin + cloud.points[i].cast<double>();
}

// The message of the ScanError that `read` throws, or "" (with a test failure) when it does not.
template <typename F>
std::string ErrorOf(F&& read) {
  try {
    read();
  } catch (const ScanError& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected a ScanError, got another exception: " << e.what();
    return "";
  }
  ADD_FAILURE() << "expected a ScanError";
  return "";
}

}  // namespace forestmap::client::testing_util
