#pragma once

// Real forest data for tests lives in ../shared/data (FORESTMAP_SHARED_DATA). A test that needs it
// and does not find it skips with a message on a developer's machine, but FAILS under CI
// (CI=true), where the data is always there: a missing folder must never turn CI green.

#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>

namespace forestmap::test {

inline bool RunningInCi() {
  const char* ci = std::getenv("CI");
  return ci != nullptr && std::strcmp(ci, "true") == 0;
}

}  // namespace forestmap::test

// Use as `if (!exists(path)) FORESTMAP_SKIP_WITHOUT_DATA() << "missing " << path;`.
#define FORESTMAP_SKIP_WITHOUT_DATA()                                          \
  return GTEST_MESSAGE_("real data missing (CI=true requires ../shared/data)", \
                        ::forestmap::test::RunningInCi()                       \
                            ? ::testing::TestPartResult::kFatalFailure         \
                            : ::testing::TestPartResult::kSkip)
