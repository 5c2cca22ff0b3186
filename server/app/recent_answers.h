#pragma once
// What the service answered: the last relocalization answers, for the read-only web page
// (server/http/http_page.h), and the count of every kind of answer since the start, for the
// metrics. Thread-safe; bounded.

#include <chrono>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "algorithms/relocalization/relocalizer.h"
#include "algorithms/relocalization/tracking.h"
#include "geo/crs.h"

namespace forestmap::server {

struct RecentAnswer {
  std::string map_name;
  int64_t unix_ms = 0;  // when it was answered, ms since the Unix epoch
  algorithms::RelocalizeStatus status = algorithms::RelocalizeStatus::kNotFound;
  int inliers = 0;
  std::optional<Eigen::Vector3d> position;    // m, map frame: the sensor's, when localized
  std::optional<geo::GeodeticPose> geodetic;  // when localized in a map with a known CRS
};

class RecentAnswers {
 public:
  static constexpr size_t kKept = 50;  // answers kept, newest first

  void Add(const std::string& map_name, const algorithms::RelocalizeResult& result,
           const std::optional<geo::GeodeticPose>& geodetic) {
    RecentAnswer answer;
    answer.map_name = map_name;
    answer.unix_ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                         std::chrono::system_clock::now().time_since_epoch())
                         .count();
    answer.status = result.status;
    answer.inliers = result.inliers;
    if (result.status == algorithms::RelocalizeStatus::kLocalized) {
      answer.position = result.map_from_sensor.translation();
    }
    answer.geodetic = geodetic;
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

// Answers by kind since the service started: Relocalize by (status, reason), Track frames by
// state. The keys are the algorithms' enums, a handful each: the counts stay bounded.
class AnswerCounts {
 public:
  using RelocalizeKey = std::pair<algorithms::RelocalizeStatus, algorithms::RelocalizeReason>;

  void Relocalized(const algorithms::RelocalizeResult& result) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++relocalized_[{result.status, result.reason}];
  }
  void Tracked(algorithms::TrackState state) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++tracked_[state];
  }
  std::map<RelocalizeKey, int64_t> relocalized() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return relocalized_;
  }
  std::map<algorithms::TrackState, int64_t> tracked() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return tracked_;
  }

 private:
  mutable std::mutex mutex_;
  std::map<RelocalizeKey, int64_t> relocalized_;
  std::map<algorithms::TrackState, int64_t> tracked_;
};

}  // namespace forestmap::server
