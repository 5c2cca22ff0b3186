// forestmap-lab bench-server: relocalization throughput of a running forestmapd. Several client
// threads, each with its own channel, send the frames of a file round-robin for a fixed number
// of requests; prints requests per second, client-side latency percentiles and the outcomes.

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "algorithms/evaluation/reloc_evaluation.h"
#include "client/io/tree_csv.h"
#include "client/lab/lab_commands.h"

namespace forestmap::client {
namespace {

// "a,b,c" started at replica `first`: "b,c,a" for first = 1, so that client threads spread over
// the replicas of --server.
std::string RotateReplicas(const std::string& servers, size_t first) {
  std::vector<std::string> list;
  std::stringstream in(servers);
  for (std::string one; std::getline(in, one, ',');) list.push_back(one);
  std::string rotated;
  for (size_t k = 0; k < list.size(); ++k) {
    rotated += (k == 0 ? "" : ",") + list[(first + k) % list.size()];
  }
  return rotated;
}

struct ServerBenchOptions {
  std::string map_name, frames_path;
  int concurrency = 8;
  int requests = 2000;
};

void Run(const ServerBenchOptions& o, CliContext& context) {
  const std::vector<Frame> frames = ReadFramesCsv(o.frames_path);
  if (frames.empty()) throw CommandError(o.frames_path + ": no frames");
  context.Connect().GetMap(o.map_name);  // fails early, with a clear message, if absent
  std::atomic<int> next{0};
  std::atomic<int> localized{0};
  std::atomic<int64_t> retries{0};
  std::vector<std::vector<double>> latencies(o.concurrency);
  const auto start = std::chrono::steady_clock::now();
  std::vector<std::thread> threads;
  std::exception_ptr failure;
  std::mutex failure_mutex;
  for (int t = 0; t < o.concurrency; ++t) {
    threads.emplace_back([&, t] {
      try {
        ForestMapClient client(RotateReplicas(context.server, static_cast<size_t>(t)));
        for (int i = next++; i < o.requests; i = next++) {
          const Frame& frame = frames[i % frames.size()];
          const auto sent = std::chrono::steady_clock::now();
          const auto response =
              client.Relocalize(o.map_name, frame.trees, std::nullopt, std::nullopt);
          latencies[t].push_back(
              std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - sent)
                  .count());
          localized += response.status() == v1::RelocalizeResponse::STATUS_LOCALIZED;
        }
        retries += client.retries();
      } catch (...) {
        std::lock_guard<std::mutex> lock(failure_mutex);
        failure = std::current_exception();
        next = o.requests;  // stop the others
      }
    });
  }
  for (auto& thread : threads) thread.join();
  if (failure) std::rethrow_exception(failure);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::vector<double> all;
  for (const auto& l : latencies) all.insert(all.end(), l.begin(), l.end());
  nlohmann::ordered_json report = {{"requests", all.size()},
                                   {"concurrency", o.concurrency},
                                   {"seconds", seconds},
                                   {"requests_per_second", all.size() / seconds},
                                   {"localized", localized.load()},
                                   {"latency_p50_ms", algorithms::Percentile(all, 0.5)},
                                   {"latency_p95_ms", algorithms::Percentile(all, 0.95)},
                                   {"latency_p99_ms", algorithms::Percentile(all, 0.99)},
                                   {"retried_on_another_replica", retries.load()}};
  *context.out << report.dump() << "\n";
}

}  // namespace

void AddBenchServerCommand(CLI::App& app, CliContext& context) {
  auto options = std::make_shared<ServerBenchOptions>();
  CLI::App* cmd =
      app.add_subcommand("bench-server",
                         "Measure a running forestmapd's relocalization throughput with concurrent "
                         "requests (frames of a file, round-robin)");
  cmd->add_option("NAME", options->map_name, "Map to relocalize in")->required();
  cmd->add_option("--frames", options->frames_path, "Frames CSV (frame,x,y,z,...)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--concurrency", options->concurrency, "Client threads")
      ->check(CLI::Range(1, 256))
      ->capture_default_str();
  cmd->add_option("--requests", options->requests, "Requests in all")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->callback(
      [options, &context] { context.run = [options, &context] { Run(*options, context); }; });
}

}  // namespace forestmap::client
