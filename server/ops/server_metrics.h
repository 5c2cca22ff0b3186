#pragma once
// What forestmapd's metrics page shows besides the RPCs (server/ops/metrics.h), registered by its
// main:
//   forestmap_index_builds_total, forestmap_index_build_seconds_total, forestmap_index_cache_maps,
//   forestmap_index_cache_bytes, forestmap_index_bytes{map}    relocalization indexes
//   forestmap_database_bytes                                   the SQLite file and its WAL
//   forestmap_relocalizations_total{status,reason}             Relocalize answers
//   forestmap_track_frames_total{state}                        Track answers
//   forestmap_ready                                            1 when ready
//   (server/app/readiness.h) process_cpu_seconds_total, process_resident_memory_bytes,
//   process_virtual_memory_bytes, process_open_fds, process_max_fds, process_start_time_seconds
//   (Prometheus' standard names)

#include <string>

namespace forestmap::server {

class Metrics;
class MapIndexCache;
class AnswerCounts;
class Readiness;

// Every object passed must outlive `metrics`' scrapes.
void AddServerMetrics(Metrics& metrics, const MapIndexCache& cache, const AnswerCounts& answers,
                      const std::string& db_path);
void AddReadinessMetric(Metrics& metrics, const Readiness& readiness);
void AddProcessMetrics(Metrics& metrics);
void AddBuildInfo(Metrics& metrics);

}  // namespace forestmap::server
