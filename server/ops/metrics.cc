#include "server/ops/metrics.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <utility>

#include "proto/status_code_name.h"

namespace forestmap::server {
namespace {

// Prometheus' text format wants floats in Go's notation: plain numbers, "+Inf", "NaN".
std::string Number(double value) {
  if (std::isnan(value)) return "NaN";
  if (std::isinf(value)) return value > 0 ? "+Inf" : "-Inf";
  // The shortest form that reads back as the same double (0.0025, not 0.0025000000000000001).
  char text[32];
  for (int precision = 1; precision <= 17; ++precision) {
    std::snprintf(text, sizeof text, "%.*g", precision, value);
    if (std::strtod(text, nullptr) == value) break;
  }
  return text;
}

void Header(std::string& out, std::string_view name, std::string_view help, std::string_view type) {
  out.append("# HELP ").append(name).append(" ").append(help).append("\n");
  out.append("# TYPE ").append(name).append(" ").append(type).append("\n");
}

}  // namespace

const std::vector<double>& Metrics::LatencyBuckets() {
  static const std::vector<double> buckets = {0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25,
                                              0.5,   1,      2.5,   5,    10,    30,   120};
  return buckets;
}

void Metrics::RpcStarted(std::string_view rpc, bool streaming) {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = rpcs_.find(rpc);
  if (it == rpcs_.end()) it = rpcs_.emplace(std::string(rpc), RpcStats{}).first;
  ++it->second.in_flight;
  if (streaming) ++open_streams_;
}

void Metrics::RpcFinished(std::string_view rpc, bool streaming, grpc::StatusCode code,
                          double seconds) {
  const std::vector<double>& bounds = LatencyBuckets();
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = rpcs_.find(rpc);
  if (it == rpcs_.end()) it = rpcs_.emplace(std::string(rpc), RpcStats{}).first;
  RpcStats& stats = it->second;
  if (stats.buckets.empty()) stats.buckets.assign(bounds.size(), 0);
  --stats.in_flight;
  if (streaming) --open_streams_;
  ++stats.by_code[code];
  ++stats.count;
  stats.seconds += seconds;
  for (size_t i = 0; i < bounds.size(); ++i) {
    if (seconds <= bounds[i]) {
      ++stats.buckets[i];
      break;
    }
  }
}

void Metrics::AddGauge(std::string name, std::string help, Sample sample) {
  std::lock_guard<std::mutex> lock(mutex_);
  sampled_.push_back({std::move(name), std::move(help), "gauge", std::move(sample)});
}

void Metrics::AddCounter(std::string name, std::string help, Sample sample) {
  std::lock_guard<std::mutex> lock(mutex_);
  sampled_.push_back({std::move(name), std::move(help), "counter", std::move(sample)});
}

void Metrics::RenderRpcs(std::string& out) const {
  Header(out, "forestmap_rpc_requests_total", "Finished RPCs by method and status code.",
         "counter");
  for (const auto& [rpc, stats] : rpcs_) {
    for (const auto& [code, count] : stats.by_code) {
      out += "forestmap_rpc_requests_total{rpc=\"" + rpc + "\",code=\"" + StatusCodeName(code) +
             "\"} " + std::to_string(count) + "\n";
    }
  }
  Header(out, "forestmap_rpc_duration_seconds", "RPC latency from start to status, seconds.",
         "histogram");
  const std::vector<double>& bounds = LatencyBuckets();
  for (const auto& [rpc, stats] : rpcs_) {
    if (stats.count == 0) continue;
    int64_t cumulative = 0;
    for (size_t i = 0; i < bounds.size(); ++i) {
      cumulative += stats.buckets[i];
      out += "forestmap_rpc_duration_seconds_bucket{rpc=\"" + rpc + "\",le=\"" + Number(bounds[i]) +
             "\"} " + std::to_string(cumulative) + "\n";
    }
    const std::string label = "{rpc=\"" + rpc + "\"";
    out += "forestmap_rpc_duration_seconds_bucket" + label + ",le=\"+Inf\"} " +
           std::to_string(stats.count) + "\n";
    out += "forestmap_rpc_duration_seconds_sum" + label + "} " + Number(stats.seconds) + "\n";
    out +=
        "forestmap_rpc_duration_seconds_count" + label + "} " + std::to_string(stats.count) + "\n";
  }
  Header(out, "forestmap_rpc_in_flight", "RPCs running now.", "gauge");
  for (const auto& [rpc, stats] : rpcs_) {
    out += "forestmap_rpc_in_flight{rpc=\"" + rpc + "\"} " + std::to_string(stats.in_flight) + "\n";
  }
  Header(out, "forestmap_open_streams", "Streaming RPCs (upload, export, track) open now.",
         "gauge");
  out += "forestmap_open_streams " + std::to_string(open_streams_) + "\n";
}

std::string Metrics::Render() const {
  std::string out;
  std::vector<Sampled> sampled;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    RenderRpcs(out);
    sampled = sampled_;
  }
  // Samples run without the lock: they may take their own (index cache, file system).
  for (const Sampled& metric : sampled) {
    Header(out, metric.name, metric.help, metric.type);
    double value = NAN;
    try {
      value = metric.sample();
    } catch (...) {
      // A failing sample (a vanished file) reads NaN rather than failing the scrape.
    }
    out += metric.name + " " + Number(value) + "\n";
  }
  return out;
}

}  // namespace forestmap::server
