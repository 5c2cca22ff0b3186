#pragma once
// The last relocalization answers the service gave, for the read-only web page (http_page.h).
// Thread-safe; bounded.

#include <chrono>
#include <cstdint>
#include <deque>
#include <mutex>
#include <string>
#include <vector>

#include "forestmap/v1/relocalization.pb.h"

namespace forestmap::server {

struct RecentAnswer {
  std::string map_name;
  int64_t unix_ms = 0;
  v1::RelocalizeResponse response;  // without its matches (kept small)
};

class RecentAnswers {
 public:
  static constexpr size_t kKept = 50;  // answers kept, newest first

  void Add(const std::string& map_name, const v1::RelocalizeResponse& response) {
    RecentAnswer answer{map_name,
                        std::chrono::duration_cast<std::chrono::milliseconds>(
                            std::chrono::system_clock::now().time_since_epoch())
                            .count(),
                        response};
    answer.response.clear_matches();
    std::lock_guard<std::mutex> lock(mutex_);
    answers_.push_front(std::move(answer));
    if (answers_.size() > kKept) answers_.pop_back();
  }
  std::vector<RecentAnswer> Get() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return {answers_.begin(), answers_.end()};
  }

 private:
  mutable std::mutex mutex_;
  std::deque<RecentAnswer> answers_;
};

}  // namespace forestmap::server
