#include "server/app/worker_pool.h"

#include <exception>
#include <stdexcept>
#include <string>
#include <utility>

namespace forestmap::server {

WorkerPool::WorkerPool(int threads, size_t max_queued, FaultReport report)
    : max_queued_(max_queued), report_(std::move(report)) {
  if (threads < 1) throw std::invalid_argument("WorkerPool needs at least 1 thread");
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
