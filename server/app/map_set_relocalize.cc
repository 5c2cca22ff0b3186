#include "server/app/map_set_relocalize.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <set>

namespace forestmap::server {
namespace {

using algorithms::RelocalizeReason;
using algorithms::RelocalizeResult;
using algorithms::RelocalizeStatus;

double Yaw(const algorithms::Pose3& pose) {
  return std::atan2(pose.linear()(1, 0), pose.linear()(0, 0));
}

// Whether two maps' poses are the same place (maps of one frame), by the relocalizer's own
// measure of distinct poses.
bool SamePlace(const algorithms::Pose3& a, const algorithms::Pose3& b,
               const algorithms::RelocalizerOptions& options) {
  const double apart = (a.translation().head<2>() - b.translation().head<2>()).norm();
  const double turn = std::abs(std::remainder(Yaw(a) - Yaw(b), 2 * M_PI));
  return apart <= options.distinct_distance && turn <= options.distinct_yaw;
}

RelocalizeResult NoMapSearched(const algorithms::RelocalizeQuery& query) {
  RelocalizeResult result;
  result.status = RelocalizeStatus::kNotFound;
  if (query.prior) {
    result.reason = RelocalizeReason::kOutsidePrior;
    result.detail = "no map of the set reaches within the prior's radius of its position";
  } else {
    result.reason = RelocalizeReason::kNoMatchingConstellation;
    result.detail = "no map of the set has confirmed trees to search";
  }
  return result;
}

// The question's AMBIGUOUS answer from `best`'s map, against `rival` of another map.
RelocalizeResult AcrossMaps(const MapAnswer& best, const MapAnswer& rival) {
  RelocalizeResult result = best.result;
  result.status = RelocalizeStatus::kAmbiguous;
  result.reason = RelocalizeReason::kAmbiguous;
  result.rival_map_from_sensor = rival.result.map_from_sensor;
  result.covariance.setZero();
  result.confidence = 0;
  if (rival.result.status == RelocalizeStatus::kLocalized) {
    const double apart = (best.result.map_from_sensor.translation().head<2>() -
                          rival.result.map_from_sensor.translation().head<2>())
                             .norm();
    char numbers[96];
    std::snprintf(numbers, sizeof numbers, " (%d and %d inliers, %.1f m apart)",
                  best.result.inliers, rival.result.inliers, apart);
    result.detail = "the view fits maps '" + best.map + "' and '" + rival.map +
                    "' at poses that disagree" + numbers;
  } else {
    result.detail = "the view fits map '" + best.map + "', and map '" + rival.map +
                    "' in several places (" + rival.result.detail + ")";
  }
  return result;
}

// The searches of a question: maps grouped by CRS (a map without one alone), in the order of
// each group's first map.
std::vector<std::vector<storage::MapInfo>> Searches(const std::vector<storage::MapInfo>& maps) {
  std::vector<std::vector<storage::MapInfo>> searches;
  for (const storage::MapInfo& info : maps) {
    const auto same_frame = std::find_if(searches.begin(), searches.end(), [&](const auto& group) {
      return !info.crs.empty() && group.front().crs == info.crs;
    });
    if (same_frame == searches.end()) {
      searches.push_back({info});
    } else {
      same_frame->push_back(info);
    }
  }
  return searches;
}

// The search of `maps` (one frame), ready to run: the map's own index, or their union's.
struct Search {
  MapAnswer answer;
  std::shared_ptr<const MapUnion> union_;  // null for one map
};

Search Prepare(MapIndexCache& cache, const std::vector<storage::MapInfo>& maps) {
  Search search;
  if (maps.size() == 1) {
    search.answer.map = maps.front().name;
    search.answer.entry = cache.Get(maps.front().name);
    return search;
  }
  search.union_ = cache.unions().Get(maps);
  search.answer.entry.index = search.union_->index;
  search.answer.entry.to_wgs84 = search.union_->to_wgs84;
  return search;
}

// A union's answer in its maps' terms: the map holding most of the matched trees answers, with
// its version; each match's id and map are its own map's.
void NameTheMaps(const MapUnion& maps, MapAnswer& answer) {
  const MapUnion::Member& answering = maps.members[maps.MostMatched(answer.result.matches)];
  answer.map = answering.name;
  answer.entry.version = answering.version;
  answer.entry.created_unix_ms = answering.created_unix_ms;
  for (algorithms::TreeMatch& match : answer.result.matches) {
    const MapUnion::Origin& origin = maps.origin.at(match.map_tree_id);
    match.map_tree_id = origin.id;
    answer.match_maps.push_back(maps.members[origin.member].name);
  }
}

}  // namespace

double ViewRange(const algorithms::RelocalizeQuery& query,
                 const algorithms::RelocalizerOptions& options) {
  double range = 0;
  for (const algorithms::DetectedTree& tree : query.trees) {
    range = std::max(range, tree.position.norm());  // >= its horizontal range at any tilt
  }
  return std::min(range, options.max_query_range);
}

bool MayHoldSensor(const storage::Extent& extent, const algorithms::PriorPose& prior,
                   double range) {
  const double x = prior.map_from_sensor.translation().x();
  const double y = prior.map_from_sensor.translation().y();
  const double dx = std::max({extent.min_x - x, 0.0, x - extent.max_x});
  const double dy = std::max({extent.min_y - y, 0.0, y - extent.max_y});
  return std::hypot(dx, dy) <= prior.radius + range;
}

std::vector<storage::MapInfo> CandidateMaps(const std::vector<storage::MapInfo>& maps,
                                            const algorithms::RelocalizeQuery& query,
                                            const algorithms::RelocalizerOptions& options) {
  const double range = ViewRange(query, options);
  const auto may_hold = [&](const storage::MapInfo& info) {
    return !query.prior || MayHoldSensor(*info.extent, *query.prior, range);
  };
  std::set<std::string> crs_met;  // CRSs of maps the prior meets: their unions are searched
  for (const storage::MapInfo& info : maps) {
    if (info.confirmed_count > 0 && info.extent && !info.crs.empty() && may_hold(info)) {
      crs_met.insert(info.crs);
    }
  }
  std::vector<storage::MapInfo> candidates;
  for (const storage::MapInfo& info : maps) {
    if (info.confirmed_count == 0 || !info.extent) continue;
    if (may_hold(info) || crs_met.count(info.crs) > 0) candidates.push_back(info);
  }
  return candidates;
}

storage::MapInfo MapNamed(const std::string& name) {
  storage::MapInfo info;
  info.name = name;
  return info;
}

size_t SearchCount(const std::vector<storage::MapInfo>& maps) { return Searches(maps).size(); }

MapSetAnswer RelocalizeInMaps(MapIndexCache& cache, const std::vector<storage::MapInfo>& maps,
                              const algorithms::RelocalizeQuery& query,
                              const algorithms::RelocalizerOptions& options) {
  MapSetAnswer out;
  if (maps.empty()) {
    out.result = NoMapSearched(query);
    return out;
  }
  const std::vector<std::vector<storage::MapInfo>> groups = Searches(maps);
  std::vector<Search> searches;
  double total_area = 0;
  for (const std::vector<storage::MapInfo>& group : groups) {
    Search& search = searches.emplace_back(Prepare(cache, group));
    if (groups.size() > 1) {  // one search alone: nothing to add to its own look-elsewhere test
      search.answer.search_area =
          algorithms::QuerySearchArea(*search.answer.entry.index, query, options);
    }
    total_area += search.answer.search_area;
  }
  algorithms::RelocalizeQuery own = query;  // one copy of the trees for every search
  for (Search& search : searches) {
    MapAnswer& answer = search.answer;
    own.other_search_area = std::max(0.0, total_area - answer.search_area);
    answer.result = algorithms::Relocalize(*answer.entry.index, own, options);
    if (search.union_) NameTheMaps(*search.union_, answer);
    out.answers.push_back(std::move(answer));
  }
  // The best of each status: most inliers.
  const auto best_with = [&](RelocalizeStatus status) {
    std::optional<size_t> best;
    for (size_t i = 0; i < out.answers.size(); ++i) {
      if (out.answers[i].result.status != status) continue;
      if (!best || out.answers[i].result.inliers > out.answers[*best].result.inliers) best = i;
    }
    return best;
  };
  const std::optional<size_t> localized = best_with(RelocalizeStatus::kLocalized);
  const std::optional<size_t> ambiguous = best_with(RelocalizeStatus::kAmbiguous);
  if (!localized) {
    out.reported = ambiguous ? ambiguous : best_with(RelocalizeStatus::kNotFound);
    out.result = out.answers[*out.reported].result;
    return out;
  }
  out.reported = localized;
  const MapAnswer& best = out.answers[*localized];
  for (size_t i = 0; i < out.answers.size() && !out.rival; ++i) {
    const RelocalizeResult& other = out.answers[i].result;
    if (i == *localized) continue;
    if (other.status == RelocalizeStatus::kAmbiguous ||
        (other.status == RelocalizeStatus::kLocalized &&
         !SamePlace(other.map_from_sensor, best.result.map_from_sensor, options))) {
      out.rival = i;
    }
  }
  if (out.rival) {
    out.result = AcrossMaps(best, out.answers[*out.rival]);
    return out;
  }
  // Maps that agree: the one whose coverage holds the sensor's position names it.
  const Eigen::Vector2d sensor = best.result.map_from_sensor.translation().head<2>();
  for (size_t i = 0; i < out.answers.size(); ++i) {
    const MapAnswer& answer = out.answers[i];
    if (answer.result.status == RelocalizeStatus::kLocalized &&
        answer.entry.index->Covers(sensor) &&
        !out.answers[*out.reported].entry.index->Covers(sensor)) {
      out.reported = i;
    }
  }
  out.result = out.answers[*out.reported].result;
  return out;
}

}  // namespace forestmap::server
