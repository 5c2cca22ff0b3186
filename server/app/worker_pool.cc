#include "server/app/worker_pool.h"

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <exception>
#include <stdexcept>
#include <string>
#include <utility>

namespace forestmap::server {

WorkerPool::WorkerPool(int threads, size_t max_queued, FaultReport report, int nice)
    : max_queued_(max_queued), report_(std::move(report)) {
  if (threads < 1) throw std::invalid_argument("WorkerPool needs at least 1 thread");
  if (nice < 0 || nice > 19) throw std::invalid_argument("WorkerPool needs 0 <= nice <= 19");
  nice_ = std::min(19, getpriority(PRIO_PROCESS, 0) + nice);  // Linux: this thread's
  if (max_queued < 1) throw std::invalid_argument("WorkerPool needs max_queued >= 1");
  if (!report_) throw std::invalid_argument("WorkerPool needs a report for jobs that throw");
  threads_.reserve(threads);
  for (int i = 0; i < threads; ++i) threads_.emplace_back([this] { Run(); });
}

WorkerPool::~WorkerPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  for (std::thread& thread : threads_) thread.join();
}

bool WorkerPool::TrySubmit(std::function<void()> job) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stopping_ || queue_.size() >= max_queued_) return false;
    queue_.push_back(std::move(job));
  }
  wake_.notify_one();
  return true;
}

void WorkerPool::Run() {
  // Linux: PRIO_PROCESS with a thread id sets that thread's nice value alone. Raising it needs no
  // privilege; a failure leaves the thread at the process's priority.
  if (nice_ != getpriority(PRIO_PROCESS, 0)) {
    setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), nice_);
  }
  for (;;) {
    std::function<void()> job;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      wake_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stopping and drained
      job = std::move(queue_.front());
      queue_.pop_front();
    }
    try {
      job();
    } catch (const std::exception& e) {
      report_(std::string("worker job threw: ") + e.what());
    } catch (...) {
      report_("worker job threw an unknown exception");
    }
  }
}

}  // namespace forestmap::server
