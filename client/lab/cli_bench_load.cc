// forestmap-lab bench-load: a mixed load on a running forestmapd for a fixed time. N client
// threads, each with its own channel, loop over four kinds of call chosen at random by weight:
//   relocalize  one frame of --frames in the shared map NAME (no prior);
//   track       a Track session of --track-frames consecutive frames with odometry from --poses;
//   observe     --observe-frames frames with their poses into the client's own map (or all into
//               the map --observe-into);
//   upload      a replace upload of the client's --upload-trees trees into its own map.
// Per-client maps (PREFIX-c<k>) are created before the clock starts (trees of --trees nearest
// the client's stretch of the route) and deleted afterwards. Reports, per kind, calls, failures
// by status (RESOURCE_EXHAUSTED apart) and latency percentiles of the successful calls, and the
// server's resident memory sampled from /proc/PID/status (--server-pid) during the run.

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <fstream>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <sstream>
#include <thread>

#include "algorithms/evaluation/reloc_evaluation.h"
#include "client/io/tree_csv.h"
#include "client/lab/lab_commands.h"

namespace forestmap::client {
namespace {

using Clock = std::chrono::steady_clock;

enum Kind { kRelocalize, kTrack, kObserve, kUpload, kKinds };
constexpr const char* kKindNames[kKinds] = {"relocalize", "track", "observe", "upload"};
// Frames each client's track and observe calls draw from (its stretch of the route).
constexpr size_t kClientWindowFrames = 20;
constexpr double kPatchRadiusM = 60.0;  // m: the client map's trees are taken within this range

struct LoadBenchOptions {
  std::string map_name;                     // shared map for relocalize and track
  std::string frames_path;                  // frames CSV (sensor frame detections)
  std::string poses_path;                   // poses CSV: map_from_sensor of each frame
  std::string trees_path;                   // map trees CSV: the source of the per-client maps
  int clients = 64;                         // client threads
  double duration_s = 60;                   // s, how long the load runs
  std::vector<int> weights = {4, 2, 2, 2};  // relocalize, track, observe, upload
  int track_frames = 5;                     // frames per Track session
  int observe_frames = 2;                   // frames per Observe call
  int upload_trees = 300;                   // trees per client map and per upload
  int server_pid = 0;                       // forestmapd's pid for RSS samples (0: none)
  double rss_interval_s = 5;                // s between RSS samples
  double warmup_s = -1;               // s excluded from the RSS range (<0: a quarter of the run)
  double pause_ms = 0;                // ms each client waits between calls
  std::string prefix = "bench-load";  // per-client maps are PREFIX-c<k>
  std::string observe_map;            // set: every client observes into this map, not its own
  bool keep_maps = false;             // leave the per-client maps (e.g. on a throwaway database)
};

struct KindStats {
  int64_t calls = 0;
  int64_t resource_exhausted = 0;
  std::map<std::string, int64_t> failed;  // by status name (not RESOURCE_EXHAUSTED)
  std::vector<double> latency_ms;         // successful calls
  int64_t localized = 0;  // relocalize: LOCALIZED answers; track: TRACKING or RECOVERED frames
};

struct Input {
  std::vector<Frame> frames;
  std::map<int64_t, algorithms::Pose3> poses;
  std::vector<MapTreeRow> trees;
};

// Everything one client thread owns.
struct Client {
  int index = 0;
  std::string own_map;
  size_t window = 0;              // first frame of its stretch of the route
  std::vector<MapTreeRow> patch;  // its map's trees (uploaded with replace)
  std::mt19937 random;
  KindStats stats[kKinds];
};

double MsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// Runs `call`; false when it failed, counted in `stats` by status (as one call).
template <typename Call>
bool Attempt(KindStats& stats, const Call& call) {
  try {
    call();
    return true;
  } catch (const RpcError& error) {
    if (error.code() == grpc::StatusCode::RESOURCE_EXHAUSTED) {
      ++stats.resource_exhausted;
    } else {
      ++stats.failed[StatusCodeName(error.code())];
    }
  } catch (const std::exception&) {
    ++stats.failed["CLIENT_ERROR"];
  }
  ++stats.calls;
  return false;
}

// One call: its latency when it succeeded, else its status.
template <typename Call>
bool Measure(KindStats& stats, const Call& call) {
  const auto start = Clock::now();
  if (!Attempt(stats, call)) return false;
  ++stats.calls;
  stats.latency_ms.push_back(MsSince(start));
  return true;
}

std::optional<algorithms::Pose3> PoseOf(const Input& input, int64_t frame) {
  const auto found = input.poses.find(frame);
  if (found == input.poses.end()) return std::nullopt;
  return found->second;
}

// The `count` trees nearest the pose of frame `window` (within kPatchRadiusM).
std::vector<MapTreeRow> Patch(const Input& input, size_t window, int count) {
  const auto pose = PoseOf(input, input.frames[window].frame);
  const Eigen::Vector3d at = pose ? Eigen::Vector3d(pose->translation()) : Eigen::Vector3d::Zero();
  std::vector<std::pair<double, size_t>> near;
  for (size_t i = 0; i < input.trees.size(); ++i) {
    const double d = std::hypot(input.trees[i].x - at.x(), input.trees[i].y - at.y());
    if (d <= kPatchRadiusM) near.emplace_back(d, i);
  }
  std::sort(near.begin(), near.end());
  near.resize(std::min(near.size(), static_cast<size_t>(count)));
  std::vector<MapTreeRow> patch;
  for (const auto& [d, i] : near) patch.push_back(input.trees[i]);
  return patch;
}

// A session of consecutive frames; each Step is one call. Opening and finishing the session
// count only when they fail.
void Track(Client& c, ForestMapClient& rpc, const Input& input, const LoadBenchOptions& o) {
  const size_t first = c.window + c.random() % kClientWindowFrames;
  KindStats& stats = c.stats[kTrack];
  std::optional<TrackSession> session;
  if (!Attempt(stats, [&] { session.emplace(rpc.Track(o.map_name)); })) return;
  const algorithms::Pose3* previous = nullptr;
  for (int k = 0; k < o.track_frames; ++k) {
    const Frame& frame = input.frames[(first + k) % input.frames.size()];
    TrackFrame step;
    step.frame_id = frame.frame;
    step.trees = frame.trees;
    const auto pose = input.poses.find(frame.frame);
    if (previous != nullptr && pose != input.poses.end()) {
      step.odometry = previous->inverse() * pose->second;
    }
    previous = pose != input.poses.end() ? &pose->second : nullptr;
    // A failed step ends the session (the server closed it; the destructor cancels ours).
    v1::TrackResponse answer;
    if (!Measure(stats, [&] { answer = session->Step(step); })) return;
    stats.localized += answer.state() == v1::TrackResponse::STATE_TRACKING ||
                       answer.state() == v1::TrackResponse::STATE_RECOVERED;
  }
  Attempt(stats, [&] { session->Finish(); });
}

void Observe(Client& c, ForestMapClient& rpc, const Input& input, const LoadBenchOptions& o) {
  std::vector<ObservedFrame> frames;
  for (int k = 0; k < o.observe_frames; ++k) {
    const Frame& frame =
        input.frames[(c.window + c.random() % kClientWindowFrames) % input.frames.size()];
    if (std::any_of(frames.begin(), frames.end(),
                    [&](const ObservedFrame& f) { return f.frame_id == frame.frame; })) {
      continue;  // frame ids are unique within a request
    }
    frames.push_back({frame.frame, frame.trees, PoseOf(input, frame.frame)});
  }
  ObserveOptions options;
  options.source = o.prefix + "-c" + std::to_string(c.index);
  const std::string& map = o.observe_map.empty() ? c.own_map : o.observe_map;
  Measure(c.stats[kObserve], [&] { rpc.Observe(map, frames, options); });
}

void OneCall(Client& c, ForestMapClient& rpc, const Input& input, const LoadBenchOptions& o,
             std::discrete_distribution<int>& pick) {
  switch (pick(c.random)) {
    case kRelocalize: {
      const Frame& frame = input.frames[c.random() % input.frames.size()];
      KindStats& stats = c.stats[kRelocalize];
      Measure(stats, [&] {
        stats.localized += rpc.Relocalize(o.map_name, frame.trees).status() ==
                           v1::RelocalizeResponse::STATUS_LOCALIZED;
      });
      break;
    }
    case kTrack:
      Track(c, rpc, input, o);
      break;
    case kObserve:
      Observe(c, rpc, input, o);
      break;
    default:
      Measure(c.stats[kUpload], [&] { rpc.UploadTrees(c.own_map, c.patch, /*replace=*/true); });
  }
}

// Resident memory of a process in MiB from /proc/PID/status (VmRSS); <0 when unreadable.
double RssMib(int pid) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(status, line);) {
    if (line.rfind("VmRSS:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;  // kB
  }
  return -1;
}

// Samples (seconds since start, MiB) every interval until `stop`.
class RssSampler {
 public:
  RssSampler(int pid, double interval_s) : pid_(pid), interval_s_(interval_s) {
    if (pid_ > 0) thread_ = std::thread([this] { Loop(); });
  }
  ~RssSampler() { Stop(); }
  void Stop() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    if (thread_.joinable()) thread_.join();
  }
  const std::vector<std::pair<double, double>>& samples() const { return samples_; }

 private:
  void Loop() {
    const auto start = Clock::now();
    std::unique_lock<std::mutex> lock(mutex_);
    while (true) {
      const double mib = RssMib(pid_);
      if (mib >= 0) samples_.emplace_back(MsSince(start) / 1000.0, mib);
      if (wake_.wait_for(lock, std::chrono::duration<double>(interval_s_),
                         [this] { return stop_; }))
        return;
    }
  }
  int pid_;
  double interval_s_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_ = false;
  std::vector<std::pair<double, double>> samples_;
  std::thread thread_;
};

Input LoadInput(const LoadBenchOptions& o) {
  Input input{ReadFramesCsv(o.frames_path), ReadPosesCsv(o.poses_path),
              ReadMapTreesCsv(o.trees_path)};
  if (input.frames.size() < kClientWindowFrames) {
    throw CommandError(o.frames_path + ": fewer than " + std::to_string(kClientWindowFrames) +
                       " frames");
  }
  return input;
}

// Per-client maps, created (again) with their trees before the clock starts.
std::vector<Client> SetUp(const Input& input, const LoadBenchOptions& o, CliContext& context) {
  ForestMapClient admin = context.Connect();
  admin.GetMap(o.map_name);  // fails early, with a clear message, if absent
  std::vector<Client> clients(o.clients);
  for (int k = 0; k < o.clients; ++k) {
    Client& c = clients[k];
    c.index = k;
    c.own_map = o.prefix + "-c" + std::to_string(k);
    c.window = (input.frames.size() - kClientWindowFrames) * k / o.clients;
    c.patch = Patch(input, c.window, o.upload_trees);
    c.random.seed(static_cast<unsigned>(k + 1));
    try {
      admin.DeleteMap(c.own_map);
    } catch (const RpcError& error) {
      if (error.code() != grpc::StatusCode::NOT_FOUND) throw;
    }
    admin.CreateMap(c.own_map, "forestmap-lab bench-load client map");
    if (!c.patch.empty()) admin.UploadTrees(c.own_map, c.patch, /*replace=*/true);
  }
  return clients;
}

void RunClients(std::vector<Client>& clients, const Input& input, const LoadBenchOptions& o,
                const CliContext& context) {
  const auto end = Clock::now() + std::chrono::duration<double>(o.duration_s);
  std::vector<std::thread> threads;
  for (Client& client : clients) {
    threads.emplace_back([&, &c = client] {
      ClientOptions options = context.client;
      options.write_attempts = 1;  // every failure counts; no retries behind the figures
      options.own_connection =
          true;  // one client, one connection (stream limits are per connection)
      ForestMapClient rpc(context.server, options);
      std::discrete_distribution<int> pick(o.weights.begin(), o.weights.end());
      while (Clock::now() < end) {
        OneCall(c, rpc, input, o, pick);
        if (o.pause_ms > 0)
          std::this_thread::sleep_for(std::chrono::duration<double, std::milli>(o.pause_ms));
      }
    });
  }
  for (auto& thread : threads) thread.join();
}

nlohmann::ordered_json KindJson(const std::vector<Client>& clients, int kind, double seconds) {
  KindStats all;
  for (const Client& c : clients) {
    const KindStats& s = c.stats[kind];
    all.calls += s.calls;
    all.resource_exhausted += s.resource_exhausted;
    all.localized += s.localized;
    for (const auto& [status, n] : s.failed) all.failed[status] += n;
    all.latency_ms.insert(all.latency_ms.end(), s.latency_ms.begin(), s.latency_ms.end());
  }
  nlohmann::ordered_json json = {{"calls", all.calls}, {"ok", all.latency_ms.size()}};
  if (kind == kRelocalize || kind == kTrack) json["localized"] = all.localized;
  json.update(nlohmann::ordered_json{{"calls_per_second", all.calls / seconds},
                                     {"failed", all.failed},
                                     {"resource_exhausted", all.resource_exhausted},
                                     {"p50_ms", algorithms::Percentile(all.latency_ms, 0.5)},
                                     {"p95_ms", algorithms::Percentile(all.latency_ms, 0.95)},
                                     {"p99_ms", algorithms::Percentile(all.latency_ms, 0.99)}});
  return json;
}

nlohmann::ordered_json RssJson(const std::vector<std::pair<double, double>>& samples,
                               double warmup_s) {
  nlohmann::ordered_json json = {{"samples", nlohmann::json::array()}};
  double low = 0, high = 0, first = -1;
  for (const auto& [t, mib] : samples) {
    json["samples"].push_back({std::round(t * 10) / 10, std::round(mib * 10) / 10});
    if (t < warmup_s) continue;
    if (first < 0) low = high = first = mib;
    low = std::min(low, mib);
    high = std::max(high, mib);
  }
  if (first >= 0) {
    json["after_warmup_s"] = warmup_s;
    json["after_warmup_min_mib"] = low;
    json["after_warmup_max_mib"] = high;
    json["final_mib"] = samples.back().second;
  }
  return json;
}

void Run(const LoadBenchOptions& o, CliContext& context) {
  if (o.weights.size() != kKinds ||
      std::any_of(o.weights.begin(), o.weights.end(), [](int w) { return w < 0; }) ||
      std::all_of(o.weights.begin(), o.weights.end(), [](int w) { return w == 0; })) {
    throw CommandError("--mix needs 4 weights >= 0 (relocalize,track,observe,upload), not all 0");
  }
  const Input input = LoadInput(o);
  std::vector<Client> clients = SetUp(input, o, context);
  *context.err << "bench-load: " << o.clients << " clients for " << o.duration_s << " s"
               << std::endl;
  RssSampler rss(o.server_pid, o.rss_interval_s);
  const auto start = Clock::now();
  RunClients(clients, input, o, context);
  const double seconds = MsSince(start) / 1000.0;
  rss.Stop();
  nlohmann::ordered_json report = {{"clients", o.clients}, {"seconds", seconds}};
  for (int kind = 0; kind < kKinds; ++kind) {
    report[kKindNames[kind]] = KindJson(clients, kind, seconds);
  }
  if (o.server_pid > 0) {
    report["server_rss"] = RssJson(rss.samples(), o.warmup_s >= 0 ? o.warmup_s : o.duration_s / 4);
  }
  *context.out << report.dump() << std::endl;
  if (o.keep_maps) return;
  ForestMapClient admin = context.Connect();
  for (const Client& c : clients) {
    try {
      admin.DeleteMap(c.own_map);
    } catch (const RpcError& error) {
      *context.err << "bench-load: warning: could not delete " << c.own_map << ": " << error.what()
                   << std::endl;
    }
  }
}

}  // namespace

void AddBenchLoadCommand(CLI::App& app, CliContext& context) {
  auto o = std::make_shared<LoadBenchOptions>();
  CLI::App* cmd = app.add_subcommand(
      "bench-load",
      "Mixed load on a running forestmapd for a fixed time: N clients relocalizing, tracking, "
      "observing into and uploading to their own maps; latency, failures and server memory");
  cmd->add_option("NAME", o->map_name, "Shared map to relocalize and track in")->required();
  cmd->add_option("--frames", o->frames_path, "Frames CSV (frame,x,y,z,...; sensor frame)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--poses", o->poses_path, "Poses CSV of the frames in the map frame")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--trees", o->trees_path, "Map trees CSV: source of the per-client maps")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--clients", o->clients, "Client threads")
      ->check(CLI::Range(1, 1024))
      ->capture_default_str();
  cmd->add_option("--duration", o->duration_s, "Seconds of load")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--mix", o->weights, "Weights of relocalize,track,observe,upload")
      ->delimiter(',')
      ->expected(4)
      ->capture_default_str();
  cmd->add_option("--track-frames", o->track_frames, "Frames per Track session")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  cmd->add_option("--observe-frames", o->observe_frames, "Frames per Observe call")
      ->check(CLI::Range(1, 20))
      ->capture_default_str();
  cmd->add_option("--upload-trees", o->upload_trees, "Trees of each client map and upload")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  cmd->add_option("--server-pid", o->server_pid, "forestmapd's pid: sample its RSS (same host)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--rss-interval", o->rss_interval_s, "Seconds between RSS samples")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--warmup", o->warmup_s, "Seconds before the RSS range (default: a quarter)");
  cmd->add_option("--pause-ms", o->pause_ms, "Milliseconds each client waits between calls")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--prefix", o->prefix, "Per-client maps are PREFIX-c<k>")->capture_default_str();
  cmd->add_option("--observe-into", o->observe_map,
                  "Every client observes into this one map (default: each into its own)");
  cmd->add_flag("--keep-maps", o->keep_maps,
                "Leave the per-client maps afterwards (deleting maps with long histories is slow)");
  cmd->callback([o, &context] { context.run = [o, &context] { Run(*o, context); }; });
}

}  // namespace forestmap::client
