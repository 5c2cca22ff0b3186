#pragma once
// Test helpers for the server's concurrency tests. GatedStore: a MapStore that forwards to another
// one, counts ReadMap and GetMap calls, and can hold ReadMap of chosen maps at a gate, so tests can
// line up concurrent callers deterministically.

#include <chrono>
#include <condition_variable>
#include <functional>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "storage/map_store.h"
#include "storage/staged_writes.h"

namespace forestmap::server {

// Upper bound on waits for other threads; only turns a hang into a failure.
inline constexpr auto kSyncTimeout = std::chrono::seconds(20);

// Polls `condition` (something another thread is about to change) until true or kSyncTimeout.
inline bool Eventually(const std::function<bool()>& condition) {
  const auto deadline = std::chrono::steady_clock::now() + kSyncTimeout;
  while (!condition()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return true;
}

class GatedStore final : public storage::MapStore {
 public:
  explicit GatedStore(storage::MapStore& inner) : inner_(inner) {}

  // ReadMap(name), and ReadTreesPage(name) after an export's first page, wait until Open().
  void Close(const std::string& name) {
    std::lock_guard<std::mutex> lock(mutex_);
    closed_.insert(name);
  }
  void Open() {
    std::lock_guard<std::mutex> lock(mutex_);
    closed_.clear();
    changed_.notify_all();
  }
  int reads(const std::string& name) {
    std::lock_guard<std::mutex> lock(mutex_);
    return reads_[name];
  }
  int get_calls() {
    std::lock_guard<std::mutex> lock(mutex_);
    return get_calls_;
  }
  int uploads_begun() {  // BeginUpload calls
    std::lock_guard<std::mutex> lock(mutex_);
    return uploads_begun_;
  }
  // Waits (up to kSyncTimeout) until ReadMap(name) was entered `count` times.
  bool WaitForReads(const std::string& name, int count) {
    std::unique_lock<std::mutex> lock(mutex_);
    return changed_.wait_for(lock, kSyncTimeout, [&] { return reads_[name] >= count; });
  }

  storage::MapSnapshot ReadMap(const std::string& name) override {
    {
      std::unique_lock<std::mutex> lock(mutex_);
      ++reads_[name];
      changed_.notify_all();
      changed_.wait(lock, [&] { return closed_.count(name) == 0; });
    }
    return inner_.ReadMap(name);
  }
  storage::MapInfo GetMap(const std::string& name) override {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      ++get_calls_;
    }
    return inner_.GetMap(name);
  }
  storage::MapInfo CreateMap(const std::string& name, const std::string& description,
                             const std::string& crs) override {
    return inner_.CreateMap(name, description, crs);
  }
  std::vector<storage::MapInfo> ListMaps() override { return inner_.ListMaps(); }
  void DeleteMap(const std::string& name) override { inner_.DeleteMap(name); }
  storage::MapInfo WriteTrees(const std::string& name,
                              const std::vector<storage::TreeRecord>& trees,
                              storage::WriteMode mode) override {
    return inner_.WriteTrees(name, trees, mode);
  }
  std::vector<storage::TreeRecord> TreesInBox(const std::string& name,
                                              const storage::Extent& box) override {
    return inner_.TreesInBox(name, box);
  }
  storage::MapSnapshot ReadMapVersion(const std::string& name, int64_t version) override {
    return inner_.ReadMapVersion(name, version);
  }
  std::vector<storage::TreeRemoval> ListRemovals(const std::string& name,
                                                 int64_t after_version) override {
    return inner_.ListRemovals(name, after_version);
  }
  std::vector<storage::VersionRecord> ListVersions(const std::string& name,
                                                   int64_t limit) override {
    return inner_.ListVersions(name, limit);
  }
  storage::MapInfo RestoreVersion(const std::string& name, int64_t version) override {
    return inner_.RestoreVersion(name, version);
  }
  storage::MapInfo Merge(const std::string& name, const storage::MergeNote& note,
                         const storage::MergeFunction& merge) override {
    return inner_.Merge(name, note, [&](storage::MergeReader& reader) {
      std::this_thread::sleep_for(merge_delay);  // a slow merge, inside the write transaction
      return merge(reader);
    });
  }
  storage::PruneResult PruneVersions(const std::string& name, int64_t keep) override {
    if (before_prune) before_prune();  // may throw: a fault of the store
    return inner_.PruneVersions(name, keep);
  }
  std::unique_ptr<storage::TreeUpload> BeginUpload(const std::string& name,
                                                   const storage::UploadPlan& plan) override {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      ++uploads_begun_;
    }
    return inner_.BeginUpload(name, plan);
  }
  std::vector<storage::TreeRecord> ReadTreesPage(const std::string& name,
                                                 const storage::TreePageQuery& query) override {
    if (query.after_id) {  // pages after an export's first wait at the gate, as ReadMap
      std::unique_lock<std::mutex> lock(mutex_);
      changed_.wait(lock, [&] { return closed_.count(name) == 0; });
    }
    return inner_.ReadTreesPage(name, query);
  }
  std::optional<storage::StoredRequest> FindRequest(const std::string& request_id) override {
    return inner_.FindRequest(request_id);
  }

  std::chrono::milliseconds merge_delay{0};  // set before concurrent use
  std::function<void()> before_prune;        // runs first in PruneVersions; set before use

 private:
  storage::MapStore& inner_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::set<std::string> closed_;
  std::map<std::string, int> reads_;
  int get_calls_ = 0;
  int uploads_begun_ = 0;
};

}  // namespace forestmap::server
