#pragma once
// Up to `max_size` connections of a database, made on demand and each lent to one caller at a
// time: SQLite's WAL readers (each reader needs its own connection) and PostgreSQL's sessions.
// Thread-safe. Not a public API.

#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

namespace forestmap::storage {

template <typename Connection>
class ConnectionPool {
 public:
  using Opener = std::function<std::unique_ptr<Connection>()>;
  // False for a connection that must be closed instead of lent again (lost its server).
  using Usable = std::function<bool(const Connection&)>;

  ConnectionPool(Opener open, int max_size, Usable usable = {})
      : open_(std::move(open)), usable_(std::move(usable)), max_size_(max_size) {}
  ConnectionPool(const ConnectionPool&) = delete;
  ConnectionPool& operator=(const ConnectionPool&) = delete;

  // Runs `body` on a borrowed connection, waiting while all are lent out. The connection goes
  // back afterwards, also when `body` throws (its RAII transaction has rolled back by then).
  void With(const std::function<void(Connection&)>& body) {
    std::unique_ptr<Connection> connection = Borrow();
    try {
      body(*connection);
    } catch (...) {
      Return(std::move(connection));
      throw;
    }
    Return(std::move(connection));
  }

 private:
  std::unique_ptr<Connection> Borrow() {
    std::unique_lock<std::mutex> lock(mutex_);
    returned_.wait(lock, [&] { return !idle_.empty() || open_count_ < max_size_; });
    if (!idle_.empty()) {
      std::unique_ptr<Connection> connection = std::move(idle_.back());
      idle_.pop_back();
      return connection;
    }
    ++open_count_;  // reserve the slot, then open without holding the lock
    lock.unlock();
    try {
      return open_();
    } catch (...) {
      lock.lock();
      --open_count_;
      returned_.notify_one();
      throw;
    }
  }

  void Return(std::unique_ptr<Connection> connection) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!usable_ || usable_(*connection)) {
        idle_.push_back(std::move(connection));
      } else {
        --open_count_;  // closed: the next Borrow opens a fresh one
      }
    }
    returned_.notify_one();
  }

  Opener open_;
  Usable usable_;
  int max_size_;
  std::mutex mutex_;
  std::condition_variable returned_;
  std::vector<std::unique_ptr<Connection>> idle_;
  int open_count_ = 0;  // idle + lent out
};

}  // namespace forestmap::storage
