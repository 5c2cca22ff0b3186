// Issue 15, finding 4: the CLI's own deadline made a slow Observe time out, and its retry added
// the frames again. The client now sends a request id with every write and retries with the same
// id: however many tries it takes, the write is applied once.

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <string>

#include "client/lib/forestmap_client.h"
#include "server/grpc/server.h"
#include "server/grpc/service.h"
#include "storage/sqlite/store.h"
#include "tests/server/gated_store.h"

namespace forestmap {
namespace {

class ClientRetryTest : public ::testing::Test {
 protected:
  ClientRetryTest()
      : dir_(std::filesystem::temp_directory_path() /
             ("forestmap_retry_" + std::to_string(getpid()))),
        store_(Prepare(dir_)),
        gated_(store_),
        service_(gated_, server::ServiceOptions{}),
        runner_("127.0.0.1:0", service_) {}
  ~ClientRetryTest() override { std::filesystem::remove_all(dir_); }

  static std::string Prepare(const std::filesystem::path& dir) {
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    return (dir / "maps.db").string();
  }

  std::filesystem::path dir_;
  storage::SqliteMapStore store_;
  server::GatedStore gated_;
  server::ForestMapService service_;
  server::ServerRunner runner_;
};

std::vector<client::ObservedFrame> Frames() {
  std::vector<client::ObservedFrame> frames(2);
  for (int f = 0; f < 2; ++f) {
    frames[f].frame_id = f;
    frames[f].map_from_sensor = algorithms::PoseFromXyzYaw(f, 0, 0, 0);
    for (int t = 0; t < 5; ++t) {
      algorithms::DetectedTree tree;
      tree.position = Eigen::Vector3d(4.0 * t - f, 2.0 * (t % 2), 0);
      tree.dbh = 0.3;
      frames[f].trees.push_back(tree);
    }
  }
  return frames;
}

TEST_F(ClientRetryTest, TimedOutWritesAreRetriedWithTheSameIdAndAppliedOnce) {
  client::ClientOptions options;
  options.call_timeout = 0.5;  // s; each merge below takes 0.8 s
  options.write_attempts = 4;
  client::ForestMapClient client(runner_.address(), options);
  client.CreateMap("shared");
  const int64_t created = store_.GetMap("shared").version;
  gated_.merge_delay = std::chrono::milliseconds(800);
  // Try 1 times out at 0.5 s and its merge is refused at its commit (deadline passed); try 2
  // (same id) waits for the writer until try 1 gave up, then its own deadline passes too; ...
  // Whatever the outcome of each try, the map gets at most one new version.
  try {
    client.Observe("shared", Frames(), {});
  } catch (const client::RpcError& e) {
    EXPECT_EQ(e.code(), grpc::StatusCode::DEADLINE_EXCEEDED) << e.what();
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(4 * 800 + 500));  // merges end
  EXPECT_LE(store_.GetMap("shared").version, created + 1);
  // With time enough, one call is one version, observed once.
  gated_.merge_delay = std::chrono::milliseconds(0);
  const int64_t before = store_.GetMap("shared").version;
  const v1::ObserveResponse response = client.Observe("shared", Frames(), {});
  EXPECT_EQ(response.map_version(), before + 1);
  EXPECT_EQ(store_.GetMap("shared").version, before + 1);
}

}  // namespace
}  // namespace forestmap
