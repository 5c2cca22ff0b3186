#pragma once
// A fixed set of threads running queued jobs in FIFO order.
//
// Why the service needs it: gRPC's callback API runs handlers on a handful of gRPC threads, and
// a handler that blocks there (an index build, a big SQLite write, a wait on a lock) stalls
// every other call, health checks included. Handlers therefore hand anything that may block to
// a pool and finish their reactor from there.

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

#include "server/app/errors.h"

namespace forestmap::server {

class WorkerPool {
 public:
  // Throws std::invalid_argument unless threads >= 1, max_queued >= 1, 0 <= nice <= 19 and
  // `report` is set. `report` gets what a job that threw was thrown (a job must not throw; one
  // that does is a bug, and the pool goes on). `nice`: the pool's threads run that much nicer
  // than the thread that made the pool (Linux schedules threads apart: under a full CPU a thread
  // of nice 10 gets about a tenth of what one of nice 0 gets; alone it runs at full speed).
  WorkerPool(int threads, size_t max_queued, FaultReport report, int nice = 0);
  // Runs the jobs still queued, then joins the threads.
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  // Queues `job`; false (and the job is dropped) when max_queued jobs are already waiting.
  // Jobs must not throw; one that does is reported and the pool goes on.
  bool TrySubmit(std::function<void()> job);

 private:
  void Run();

  size_t max_queued_;
  FaultReport report_;
  int nice_;  // the threads' nice value (absolute)
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::function<void()>> queue_;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace forestmap::server
