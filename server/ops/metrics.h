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
// Label values that come from outside (the rpc label) are escaped per the text format
// (backslash, double quote, newline; other bytes outside printable ASCII become '?') and cut to
// kMaxMetricLabelBytes; past kMaxRpcSeries distinct rpc labels, new ones are counted as "unknown",
// so the page never grows with what callers send.
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

inline constexpr size_t kMaxMetricLabelBytes = 128;  // a longer label value is cut
inline constexpr size_t kMaxRpcSeries = 256;         // distinct rpc labels kept
inline constexpr const char* kUnknownRpc = "unknown";

// `value` as a label value of the text exposition format: at most kMaxMetricLabelBytes bytes of
// it, with backslash, double quote and newline escaped and other bytes outside printable ASCII
// replaced by '?'.
std::string MetricLabelValue(std::string_view value);

class Metrics {
 public:
  using Sample = std::function<double()>;
  // A labelled series: its labels as written between the braces (`status="localized"`, label
  // values through MetricLabelValue), and its value.
  struct Series {
    std::string labels;
    double value = 0;
  };
  using SampleSeries = std::function<std::vector<Series>()>;

  // Upper bounds (s) of the latency histogram buckets; +Inf is implied.
  static const std::vector<double>& LatencyBuckets();

  void RpcStarted(std::string_view rpc, bool streaming);
  void RpcFinished(std::string_view rpc, bool streaming, grpc::StatusCode code, double seconds);

  // A value read at every scrape. `name` must be a valid metric name, unique; `help` one line.
  void AddGauge(std::string name, std::string help, Sample sample);
  void AddCounter(std::string name, std::string help, Sample sample);  // must never decrease
  // The same for a family of labelled series, read at every scrape.
  void AddGaugeSeries(std::string name, std::string help, SampleSeries sample);
  void AddCounterSeries(std::string name, std::string help, SampleSeries sample);

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
    SampleSeries sample;
  };
  void AddSampled(std::string name, std::string help, std::string type, SampleSeries sample);
  void RenderRpcs(std::string& out) const;
  RpcStats& StatsOf(std::string_view rpc);  // under mutex_

  mutable std::mutex mutex_;
  std::map<std::string, RpcStats, std::less<>> rpcs_;
  int64_t open_streams_ = 0;
  std::vector<Sampled> sampled_;
};

}  // namespace forestmap::server
