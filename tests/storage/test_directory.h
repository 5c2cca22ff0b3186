#pragma once
// A fresh directory for the files of one test.

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <string>

namespace forestmap::storage {

// A directory of its own for one test (the pid too: another build's run of the same test in
// another worktree shares /tmp), removed afterwards.
class TestDirectory {
 public:
  TestDirectory() {
    static std::atomic<int> counter{0};
    const auto* test = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = "forestmap_storage_" + std::to_string(getpid()) + "_";
    name += std::to_string(counter++) + "_" + (test != nullptr ? test->name() : "");
    for (char& c : name) c = c == '/' ? '_' : c;  // parameterized names hold a slash
    path_ = std::filesystem::temp_directory_path() / name;
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TestDirectory() { std::filesystem::remove_all(path_); }
  TestDirectory(const TestDirectory&) = delete;
  TestDirectory& operator=(const TestDirectory&) = delete;
  const std::filesystem::path& path() const { return path_; }
  // A file `name` in the directory.
  std::string File(const std::string& name) const { return (path_ / name).string(); }

 private:
  std::filesystem::path path_;
};

}  // namespace forestmap::storage
