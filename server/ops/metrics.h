#pragma once
// forestmapd's Prometheus metrics, rendered in the text exposition format (version 0.0.4) for
// GET /metrics (server/http/metrics_http.h):
//   forestmap_rpc_requests_total{rpc,code}     counter   finished RPCs by status code
//   forestmap_rpc_duration_seconds{rpc}        histogram RPC latency (start to status sent)
//   forestmap_rpc_in_flight{rpc}               gauge     RPCs running now
//   forestmap_open_streams                     gauge     streaming RPCs (upload, export, track)
//   open
// plus the gauges and counters registered with AddGauge / AddCounter (index builds, index cache
// size, database size; wired in forestmapd's main).
//
// Thread-safety: all methods may be called concurrently.

#include <grpcpp/support/status.h>

#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

namespace forestmap::server {

class Metrics {
 public:
  using Sample = std::function<double()>;

  // Upper bounds (s) of the latency histogram buckets; +Inf is implied.
  static const std::vector<double>& LatencyBuckets();

  void RpcStarted(std::string_view rpc, bool streaming);
  void RpcFinished(std::string_view rpc, bool streaming, grpc::StatusCode code, double seconds);

  // A value read at every scrape. `name` must be a valid metric name, unique; `help` one line.
  void AddGauge(std::string name, std::string help, Sample sample);
  void AddCounter(std::string name, std::string help, Sample sample);  // must never decrease

  // The whole exposition text.
  std::string Render() const;

 private:
  struct RpcStats {
    std::map<grpc::StatusCode, int64_t> by_code;
    std::vector<int64_t> buckets;  // counts per LatencyBuckets() bound, not cumulative
    int64_t count = 0;             // all finished calls (also the +Inf bucket)
    double seconds = 0;            // sum of durations
    int64_t in_flight = 0;
  };
  struct Sampled {
    std::string name, help, type;
    Sample sample;
  };
  void RenderRpcs(std::string& out) const;

  mutable std::mutex mutex_;
  std::map<std::string, RpcStats, std::less<>> rpcs_;
  int64_t open_streams_ = 0;
  std::vector<Sampled> sampled_;
};

}  // namespace forestmap::server
