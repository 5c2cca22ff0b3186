// Many replicas, one truth: three real forestmapd processes on one PostgreSQL (a fresh database on
// the test cluster of tests/pg_fixture.h), driven through the real wire:
// - a map created and written through replica 1 is answered by replicas 2 and 3 on their next
//   request, and so is a new version of it (each replica's index follows the map's version);
// - four drones uploading through different replicas at once build exactly the map one
//   sequential upload builds, value for value;
// - replica 2 killed (SIGKILL) in the middle of 1,000 relocalizations: the client moves to
//   another replica and loses none, and says how many calls it retried.

#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <thread>
#include <tuple>

#include "client/io/tree_csv.h"
#include "client/lib/forestmap_client.h"
#include "tests/pg_fixture.h"

extern char** environ;

namespace forestmap {
namespace {

const std::string kData = FORESTMAP_SHARED_DATA;
const std::string kForestmapd = FORESTMAPD_PATH;
constexpr int kReplicas = 3;
constexpr int kBatch = 25;  // frames per Observe request, as `forestmap observe` sends
constexpr int kDrones = 4;
constexpr size_t kObservedFrames = 400;  // the first frames of Wild_V01 (the whole is ~1,450)
constexpr int kRelocalizations = 1000;

// One forestmapd process; killed (SIGTERM, then waited for) on destruction.
class Replica {
 public:
  explicit Replica(const std::string& db) {
    address_ = "127.0.0.1:" + std::to_string(testing::FreeLoopbackPort());
    std::vector<std::string> args = {kForestmapd, "--db", db, "--listen", address_};
    std::vector<char*> argv;
    for (std::string& arg : args) argv.push_back(arg.data());
    argv.push_back(nullptr);
    if (posix_spawn(&pid_, kForestmapd.c_str(), nullptr, nullptr, argv.data(), environ) != 0) {
      throw std::runtime_error("cannot start " + kForestmapd);
    }
    for (int attempt = 0; attempt < 100; ++attempt) {  // up to ~10 s
      try {
        // A fresh channel each time: a failed one waits out gRPC's reconnect backoff.
        client::ForestMapClient(address_).ListMaps();
        return;
      } catch (const std::exception&) {
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
      }
    }
    throw std::runtime_error("forestmapd at " + address_ + " did not come up");
  }
  ~Replica() { Stop(SIGTERM); }
  void Signal(int signal) const {
    if (pid_ > 0) kill(pid_, signal);
  }
  void Stop(int signal) {
    if (pid_ <= 0) return;
    kill(pid_, signal);
    waitpid(pid_, nullptr, 0);
    pid_ = -1;
  }
  const std::string& address() const { return address_; }

 private:
  pid_t pid_ = -1;
  std::string address_;
};

class ReplicasTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(kData + "/sequences/Wild_V01/trees.csv")) {
      GTEST_SKIP() << "real data missing under " << kData;
    }
    for (int r = 0; r < kReplicas; ++r) {
      replicas_.push_back(std::make_unique<Replica>(database_.url()));
    }
  }
  // SIGTERM to all first, then wait: each replica's shutdown grace runs in parallel.
  void TearDown() override {
    for (auto& replica : replicas_) replica->Signal(SIGTERM);
    replicas_.clear();
  }
  std::string Address(int r) const { return replicas_[static_cast<size_t>(r)]->address(); }

  testing::TestDatabase database_;
  std::vector<std::unique_ptr<Replica>> replicas_;
};

std::vector<client::Frame> Frames() {
  return client::ReadFramesCsv(kData + "/sequences/Wild_V01/trees.csv");
}

using Clock = std::chrono::steady_clock;

// `client`'s first answer for `frame` in `map` after a write (its time printed, for the record:
// it includes the replica's index build).
v1::RelocalizeResponse NextAnswer(Clock::time_point written, client::ForestMapClient& client,
                                  const std::string& map, const client::Frame& frame,
                                  const std::string& what) {
  const v1::RelocalizeResponse response = client.Relocalize(map, frame.trees);
  const double ms = std::chrono::duration<double, std::milli>(Clock::now() - written).count();
  std::cout << "[ replicas ] " << what << " answered by " << client.address() << " after " << ms
            << " ms\n";
  return response;
}

TEST_F(ReplicasTest, AWriteThroughOneReplicaIsAnsweredByAllOnTheirNextRequest) {
  const auto map_rows = client::ReadMapTreesCsv(kData + "/sequences/Wild_V01/map.csv");
  const client::Frame frame = Frames().at(300);
  client::ForestMapClient first(Address(0));
  std::vector<std::unique_ptr<client::ForestMapClient>> others;
  for (int r = 1; r < kReplicas; ++r) {
    others.push_back(std::make_unique<client::ForestMapClient>(Address(r)));
    EXPECT_THROW(others.back()->GetMap("forest"), client::RpcError);  // not there yet
  }
  first.CreateMap("forest", "", "");
  first.UploadTrees("forest", map_rows, /*replace=*/false);
  Clock::time_point written = Clock::now();
  const auto localized = [](const v1::RelocalizeResponse& response) {
    return response.status() == v1::RelocalizeResponse::STATUS_LOCALIZED;
  };
  // Replicas 2 and 3 first (timed from the write), then replica 1 for the reference pose.
  for (auto& other : others) {
    EXPECT_TRUE(localized(NextAnswer(written, *other, "forest", frame, "the new map")))
        << other->address();
  }

  const v1::RelocalizeResponse reference = first.Relocalize("forest", frame.trees);
  ASSERT_TRUE(localized(reference));

  // A new version (the whole map shifted 100 m east): every replica answers from it at once.
  auto shifted = map_rows;
  for (auto& row : shifted) row.x += 100.0;
  first.UploadTrees("forest", shifted, /*replace=*/true);
  written = Clock::now();
  const double old_x = reference.map_from_sensor().translation().x();
  const auto moved = [&](const v1::RelocalizeResponse& response) {
    return response.status() == v1::RelocalizeResponse::STATUS_LOCALIZED &&
           std::abs(response.map_from_sensor().translation().x() - (old_x + 100.0)) < 0.5;
  };
  for (auto& other : others) {
    EXPECT_TRUE(moved(NextAnswer(written, *other, "forest", frame, "the new version")))
        << other->address();
  }
}

std::vector<client::ObservedFrame> ObservedFrames() {
  const auto poses = client::ReadPosesCsv(kData + "/sequences/Wild_V01/poses.csv");
  std::vector<client::ObservedFrame> frames;
  for (client::Frame& frame : Frames()) {
    if (frames.size() == kObservedFrames) break;
    client::ObservedFrame observed;
    observed.frame_id = frame.frame;
    observed.trees = std::move(frame.trees);
    observed.map_from_sensor = poses.at(frame.frame);
    frames.push_back(std::move(observed));
  }
  return frames;
}

int Upload(client::ForestMapClient& client, const std::string& map, const std::string& source,
           const std::vector<client::ObservedFrame>& frames, size_t first, size_t last) {
  client::ObserveOptions options;
  options.merge_only = true;  // the merge alone is a function of the set of observations
  options.source = source;
  int failures = 0;
  for (size_t begin = first; begin < last; begin += kBatch) {
    const std::vector<client::ObservedFrame> batch(
        frames.begin() + static_cast<std::ptrdiff_t>(begin),
        frames.begin() + static_cast<std::ptrdiff_t>(std::min(last, begin + kBatch)));
    try {
      client.Observe(map, batch, options);
    } catch (const std::exception& e) {
      ADD_FAILURE() << e.what();
      ++failures;
    }
  }
  return failures;
}

// Every value of every tree but its id (ids follow arrival order), sorted.
using TreeValues = std::tuple<double, double, std::optional<double>, std::optional<double>, bool,
                              int64_t, std::optional<double>, std::optional<double>>;
std::vector<TreeValues> Values(client::ForestMapClient& client, const std::string& map) {
  const client::ExportedTrees exported = client.ExportTrees(map);
  std::vector<TreeValues> values;
  for (size_t i = 0; i < exported.trees.size(); ++i) {
    const auto& tree = exported.trees[i];
    const auto& state = exported.states[i];
    values.emplace_back(tree.x, tree.y, tree.z, tree.dbh, state.confirmed, state.observations,
                        state.position_sigma_m, state.dbh_sigma_m);
  }
  std::sort(values.begin(), values.end());
  return values;
}

TEST_F(ReplicasTest, FourDronesThroughThreeReplicasBuildTheSequentialMapExactly) {
  const std::vector<client::ObservedFrame> frames = ObservedFrames();
  client::ForestMapClient first(Address(0));
  first.CreateMap("sequential", "", "");
  first.CreateMap("concurrent", "", "");
  EXPECT_EQ(Upload(first, "sequential", "seq", frames, 0, frames.size()), 0);
  std::vector<std::thread> drones;
  for (int q = 0; q < kDrones; ++q) {
    drones.emplace_back([&, q] {
      client::ForestMapClient drone(Address(q % kReplicas));  // 1, 2, 3, 1
      const char* source[kDrones] = {"drone-d", "drone-c", "drone-b", "drone-a"};
      Upload(drone, "concurrent", source[q], frames, frames.size() * q / kDrones,
             frames.size() * (q + 1) / kDrones);
    });
  }
  for (std::thread& drone : drones) drone.join();
  client::ForestMapClient third(Address(2));
  const std::vector<TreeValues> sequential = Values(third, "sequential");
  const std::vector<TreeValues> concurrent = Values(third, "concurrent");
  ASSERT_GT(sequential.size(), 1000u);
  EXPECT_EQ(concurrent.size(), sequential.size());
  size_t equal = 0;
  for (size_t i = 0; i < std::min(sequential.size(), concurrent.size()); ++i) {
    equal += sequential[i] == concurrent[i];
  }
  std::cout << "[ replicas ] " << equal << " of " << sequential.size()
            << " trees equal in every value (bit for bit)\n";
  EXPECT_EQ(equal, sequential.size());
}

TEST_F(ReplicasTest, AKilledReplicaLosesNoRelocalization) {
  const auto map_rows = client::ReadMapTreesCsv(kData + "/sequences/Wild_V01/map.csv");
  const std::vector<client::Frame> frames = Frames();
  client::ForestMapClient(Address(0)).CreateMap("forest", "", "");
  client::ForestMapClient(Address(0)).UploadTrees("forest", map_rows, /*replace=*/false);
  // The client starts on replica 2, which dies half-way.
  client::ForestMapClient drone(Address(1) + "," + Address(2) + "," + Address(0));
  int answered = 0, localized = 0;
  for (int i = 0; i < kRelocalizations; ++i) {
    if (i == kRelocalizations / 2) replicas_[1]->Stop(SIGKILL);
    const client::Frame& frame = frames[static_cast<size_t>(i) % frames.size()];
    try {
      const v1::RelocalizeResponse response = drone.Relocalize("forest", frame.trees);
      ++answered;
      localized += response.status() == v1::RelocalizeResponse::STATUS_LOCALIZED;
    } catch (const client::RpcError& e) {
      // Frames with too few trees are rejected as INVALID_ARGUMENT: an answer, not a loss.
      if (e.code() != grpc::StatusCode::INVALID_ARGUMENT) ADD_FAILURE() << e.what();
      answered += e.code() == grpc::StatusCode::INVALID_ARGUMENT;
    }
  }
  std::cout << "[ replicas ] " << answered << " of " << kRelocalizations << " answered ("
            << localized << " localized), " << drone.retries()
            << " retried on another replica, finished on " << drone.current_address() << "\n";
  EXPECT_EQ(answered, kRelocalizations);
  EXPECT_GE(drone.retries(), 1);
  EXPECT_EQ(drone.current_address(), Address(2));
}

}  // namespace
}  // namespace forestmap
