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
  char text[32];
  if (value == std::trunc(value) && std::fabs(value) < 1e15) {  // counts, bytes: 20, not 2e+01
    std::snprintf(text, sizeof text, "%.0f", value);
    return text;
  }
  // The shortest form that reads back as the same double (0.0025, not 0.0025000000000000001).
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

// A single value is the series without labels.
Metrics::SampleSeries Single(Metrics::Sample sample) {
  return [sample = std::move(sample)] { return std::vector<Metrics::Series>{{"", sample()}}; };
}

}  // namespace

std::string MetricLabelValue(std::string_view value) {
  std::string out;
  for (const char c : value.substr(0, kMaxMetricLabelBytes)) {
    if (c == '\\') {
      out += "\\\\";
    } else if (c == '"') {
      out += "\\\"";
    } else if (c == '\n') {
      out += "\\n";
    } else if (c < ' ' || c > '~') {
      out += '?';  // other control bytes and non-ASCII (never split UTF-8 into invalid text)
    } else {
      out += c;
    }
  }
  return out;
}

const std::vector<double>& Metrics::LatencyBuckets() {
  static const std::vector<double> buckets = {0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25,
                                              0.5,   1,      2.5,   5,    10,    30,   120};
  return buckets;
}

Metrics::RpcStats& Metrics::StatsOf(std::string_view rpc) {
  auto it = rpcs_.find(rpc);
  if (it != rpcs_.end()) return it->second;
  if (rpcs_.size() >= kMaxRpcSeries) rpc = kUnknownRpc;
  return rpcs_.try_emplace(std::string(rpc)).first->second;
}

void Metrics::RpcStarted(std::string_view rpc, bool streaming) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++StatsOf(rpc).in_flight;
  if (streaming) ++open_streams_;
}

void Metrics::RpcFinished(std::string_view rpc, bool streaming, grpc::StatusCode code,
                          double seconds) {
  const std::vector<double>& bounds = LatencyBuckets();
  std::lock_guard<std::mutex> lock(mutex_);
  RpcStats& stats = StatsOf(rpc);
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

void Metrics::AddSampled(std::string name, std::string help, std::string type,
                         SampleSeries sample) {
  std::lock_guard<std::mutex> lock(mutex_);
  sampled_.push_back({std::move(name), std::move(help), std::move(type), std::move(sample)});
}

void Metrics::AddGauge(std::string name, std::string help, Sample sample) {
  AddSampled(std::move(name), std::move(help), "gauge", Single(std::move(sample)));
}

void Metrics::AddCounter(std::string name, std::string help, Sample sample) {
  AddSampled(std::move(name), std::move(help), "counter", Single(std::move(sample)));
}

void Metrics::AddGaugeSeries(std::string name, std::string help, SampleSeries sample) {
  AddSampled(std::move(name), std::move(help), "gauge", std::move(sample));
}

void Metrics::AddCounterSeries(std::string name, std::string help, SampleSeries sample) {
  AddSampled(std::move(name), std::move(help), "counter", std::move(sample));
}

void Metrics::RenderRpcs(std::string& out) const {
  Header(out, "forestmap_rpc_requests_total", "Finished RPCs by method and status code.",
         "counter");
  for (const auto& [name, stats] : rpcs_) {
    const std::string rpc = MetricLabelValue(name);
    for (const auto& [code, count] : stats.by_code) {
      out += "forestmap_rpc_requests_total{rpc=\"" + rpc + "\",code=\"" + StatusCodeName(code) +
             "\"} " + std::to_string(count) + "\n";
    }
  }
  Header(out, "forestmap_rpc_duration_seconds", "RPC latency from start to status, seconds.",
         "histogram");
  const std::vector<double>& bounds = LatencyBuckets();
  for (const auto& [name, stats] : rpcs_) {
    if (stats.count == 0) continue;
    const std::string rpc = MetricLabelValue(name);
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
  for (const auto& [name, stats] : rpcs_) {
    out += "forestmap_rpc_in_flight{rpc=\"" + MetricLabelValue(name) + "\"} " +
           std::to_string(stats.in_flight) + "\n";
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
    std::vector<Series> series;
    try {
      series = metric.sample();
    } catch (...) {
      // A failing sample (a vanished file) reads NaN rather than failing the scrape.
      series = {{"", NAN}};
    }
    for (const Series& one : series) {
      out.append(metric.name);
      if (!one.labels.empty()) out.append("{").append(one.labels).append("}");
      out.append(" ").append(Number(one.value)).append("\n");
    }
  }
  return out;
}

}  // namespace forestmap::server
