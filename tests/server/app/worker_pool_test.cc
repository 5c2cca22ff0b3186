// The service's thread pools (server/app/worker_pool.h): jobs run in order, a full queue refuses
// (the caller answers "busy"), a job that throws is reported and the pool goes on, and
// destruction runs what is still queued. Also run under ThreadSanitizer (threaded_tests).

#include "server/app/worker_pool.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <algorithm>
#include <future>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

namespace forestmap::server {
namespace {

using ::testing::HasSubstr;

class WorkerPoolTest : public ::testing::Test {
 protected:
  FaultReport Report() {
    return [this](std::string_view message) {
      std::lock_guard<std::mutex> lock(mutex_);
      reports_.emplace_back(message);
    };
  }
  std::vector<std::string> reports() {
    std::lock_guard<std::mutex> lock(mutex_);
    return reports_;
  }

  std::mutex mutex_;
  std::vector<std::string> reports_;
};

TEST_F(WorkerPoolTest, OneThreadRunsJobsInOrderAndDrainsOnDestruction) {
  std::vector<int> order;
  {
    WorkerPool pool(1, 100, Report());
    for (int i = 0; i < 50; ++i) ASSERT_TRUE(pool.TrySubmit([&order, i] { order.push_back(i); }));
  }
  ASSERT_EQ(order.size(), 50u);
  for (int i = 0; i < 50; ++i) EXPECT_EQ(order[i], i);
}

TEST_F(WorkerPoolTest, AFullQueueRefusesTheJob) {
  // Declared before the pool: its destructor runs the queued jobs, which use them.
  int ran = 0;
  std::promise<void> release;
  std::shared_future<void> released = release.get_future().share();
  std::promise<void> started;
  WorkerPool pool(1, 2, Report());
  EXPECT_TRUE(pool.TrySubmit([&started, released] {
    started.set_value();
    released.wait();
  }));
  started.get_future().wait();  // the thread is busy: what follows waits in the queue
  EXPECT_TRUE(pool.TrySubmit([&ran] { ++ran; }));
  EXPECT_TRUE(pool.TrySubmit([&ran] { ++ran; }));
  EXPECT_FALSE(pool.TrySubmit([&ran] { ++ran; }));  // max_queued 2 are waiting
  release.set_value();
}

TEST_F(WorkerPoolTest, AJobThatThrowsIsReportedAndThePoolGoesOn) {
  std::promise<int> after;
  {
    WorkerPool pool(2, 10, Report());
    ASSERT_TRUE(pool.TrySubmit([] { throw std::runtime_error("boom"); }));
    ASSERT_TRUE(pool.TrySubmit([] { throw 7; }));
    ASSERT_TRUE(pool.TrySubmit([&after] { after.set_value(1); }));
  }
  EXPECT_EQ(after.get_future().get(), 1);
  const std::vector<std::string> seen = reports();
  ASSERT_EQ(seen.size(), 2u);
  EXPECT_THAT(seen, ::testing::Contains(HasSubstr("boom")));
  EXPECT_THAT(seen, ::testing::Contains(HasSubstr("unknown exception")));
}

TEST_F(WorkerPoolTest, NonsenseOptionsAreRefused) {
  EXPECT_THROW(WorkerPool(0, 1, Report()), std::invalid_argument);
  EXPECT_THROW(WorkerPool(1, 0, Report()), std::invalid_argument);
  EXPECT_THROW(WorkerPool(1, 1, FaultReport()), std::invalid_argument);
  EXPECT_THROW(WorkerPool(1, 1, Report(), -1), std::invalid_argument);
  EXPECT_THROW(WorkerPool(1, 1, Report(), 20), std::invalid_argument);
}

// The service's write pool runs nicer than its read pool, so that under a full CPU writes take
// a small share of it and reads keep their throughput; the caller's own priority is unchanged.
TEST_F(WorkerPoolTest, ANicePoolsThreadsRunNicerThanItsMaker) {
  const int mine = getpriority(PRIO_PROCESS, 0);
  const auto nice_of_a_job = [&](WorkerPool& pool) {
    std::promise<int> seen;
    EXPECT_TRUE(pool.TrySubmit([&seen] { seen.set_value(getpriority(PRIO_PROCESS, 0)); }));
    return seen.get_future().get();
  };
  WorkerPool nicer(2, 10, Report(), 10);
  WorkerPool plain(2, 10, Report());
  EXPECT_EQ(nice_of_a_job(nicer), std::min(19, mine + 10));
  EXPECT_EQ(nice_of_a_job(plain), mine);
  EXPECT_EQ(getpriority(PRIO_PROCESS, 0), mine);
}

}  // namespace
}  // namespace forestmap::server
