#include "server/ops/server_metrics.h"

#include <sys/resource.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <system_error>
#include <vector>

#include "forestmap_version.h"
#include "server/app/map_index_cache.h"
#include "server/app/readiness.h"
#include "server/app/recent_answers.h"
#include "server/ops/metrics.h"

namespace forestmap::server {
namespace {

void AddIndexMetrics(Metrics& metrics, const MapIndexCache& cache) {
  const MapIndexCache* index_cache = &cache;
  metrics.AddCounter("forestmap_index_builds_total", "Relocalization indexes built.",
                     [index_cache] { return static_cast<double>(index_cache->stats().builds); });
  metrics.AddCounter("forestmap_index_build_seconds_total",
                     "Wall time spent building relocalization indexes, seconds.",
                     [index_cache] { return index_cache->stats().build_seconds; });
  metrics.AddGauge("forestmap_index_cache_maps", "Maps with an index in the cache.",
                   [index_cache] { return static_cast<double>(index_cache->size()); });
  metrics.AddGauge("forestmap_index_cache_bytes",
                   "Approximate memory of the cached indexes, bytes.",
                   [index_cache] { return static_cast<double>(index_cache->memory_bytes()); });
  // One series per cached map: at most the cache's max_entries.
  metrics.AddGaugeSeries(
      "forestmap_index_bytes", "Approximate memory of each cached map's index, bytes.",
      [index_cache] {
        std::vector<Metrics::Series> series;
        for (const auto& [name, bytes] : index_cache->memory_bytes_by_map()) {
          series.push_back({"map=\"" + MetricLabelValue(name) + "\"", static_cast<double>(bytes)});
        }
        return series;
      });
}

void AddAnswerMetrics(Metrics& metrics, const AnswerCounts& answers) {
  const AnswerCounts* counts = &answers;
  metrics.AddCounterSeries(
      "forestmap_relocalizations_total",
      "Relocalize answers by status (localized, ambiguous, not_found) and reason.", [counts] {
        std::vector<Metrics::Series> series;
        for (const auto& [key, count] : counts->relocalized()) {
          series.push_back({std::string("status=\"") + algorithms::ToString(key.first) +
                                "\",reason=\"" + algorithms::ToString(key.second) + "\"",
                            static_cast<double>(count)});
        }
        return series;
      });
  metrics.AddCounterSeries(
      "forestmap_track_frames_total",
      "Track frames answered, by state (tracking, recovered, lost).", [counts] {
        std::vector<Metrics::Series> series;
        for (const auto& [state, count] : counts->tracked()) {
          series.push_back({std::string("state=\"") + algorithms::ToString(state) + "\"",
                            static_cast<double>(count)});
        }
        return series;
      });
}

// Fields of /proc/self/statm, in pages: total program size, resident set.
std::vector<double> StatmPages() {
  std::ifstream statm("/proc/self/statm");
  double size = NAN, resident = NAN;
  statm >> size >> resident;
  return {size, resident};
}

}  // namespace

void AddServerMetrics(Metrics& metrics, const MapIndexCache& cache, const AnswerCounts& answers,
                      const std::string& db_path) {
  AddIndexMetrics(metrics, cache);
  AddAnswerMetrics(metrics, answers);
  metrics.AddGauge("forestmap_database_bytes", "Size of the database file and its WAL, bytes.",
                   [db_path] {
                     std::error_code error;
                     double bytes = 0;
                     for (const std::string& path : {db_path, db_path + "-wal"}) {
                       const auto size = std::filesystem::file_size(path, error);
                       if (!error) bytes += static_cast<double>(size);
                     }
                     return bytes;
                   });
}

void AddReadinessMetric(Metrics& metrics, const Readiness& readiness) {
  const Readiness* state = &readiness;
  metrics.AddGauge("forestmap_ready",
                   "1 when the server is ready (database reachable, preloaded indexes warm).",
                   [state] { return state->state().ready ? 1.0 : 0.0; });
}

void AddBuildInfo(Metrics& metrics) {
  const std::string labels = "version=\"" + MetricLabelValue(kVersion) + "\",commit=\"" +
                             MetricLabelValue(kGitCommit) + "\",build_type=\"" +
                             MetricLabelValue(kBuildType) + "\"";
  metrics.AddGaugeSeries("forestmap_build_info",
                         "Always 1: the version, git commit and build type of this forestmapd.",
                         [labels] {
                           return std::vector<Metrics::Series>{{labels, 1}};
                         });
}

void AddProcessMetrics(Metrics& metrics) {
  const double page_bytes = static_cast<double>(sysconf(_SC_PAGESIZE));
  const double start_s =
      std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  metrics.AddCounter("process_cpu_seconds_total", "Total user and system CPU time, seconds.", [] {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    return usage.ru_utime.tv_sec + usage.ru_stime.tv_sec +
           (usage.ru_utime.tv_usec + usage.ru_stime.tv_usec) / 1e6;
  });
  metrics.AddGauge("process_resident_memory_bytes", "Resident memory size, bytes.",
                   [page_bytes] { return StatmPages()[1] * page_bytes; });
  metrics.AddGauge("process_virtual_memory_bytes", "Virtual memory size, bytes.",
                   [page_bytes] { return StatmPages()[0] * page_bytes; });
  metrics.AddGauge("process_open_fds", "Open file descriptors.", [] {
    std::error_code error;
    double count = 0;
    for (std::filesystem::directory_iterator it("/proc/self/fd", error), end; !error && it != end;
         it.increment(error)) {
      ++count;
    }
    return error ? NAN : count;
  });
  metrics.AddGauge("process_max_fds", "Limit of open file descriptors.", [] {
    rlimit limit{};
    getrlimit(RLIMIT_NOFILE, &limit);
    return static_cast<double>(limit.rlim_cur);
  });
  metrics.AddGauge("process_start_time_seconds",
                   "Start time of the process since the Unix epoch, seconds.",
                   [start_s] { return start_s; });
}

}  // namespace forestmap::server
