// Concurrency on every backend: readers, in the same store or in another store on the same
// database (another forestmapd replica), always see a committed version whole while a writer
// replaces the map's trees. SQLite on a file reads through its pool of WAL readers, in memory
// through the one connection.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "tests/storage/store_backends.h"
#include "tests/storage/store_test_util.h"

namespace forestmap::storage {
namespace {

// Readers must always see a committed version whole: count, extent and trees agree, and every
// tree carries the batch marker of that version.
std::string CheckSnapshot(const MapSnapshot& snapshot) {
  const MapInfo& info = snapshot.info;
  if (info.tree_count != static_cast<int64_t>(snapshot.trees.size())) {
    return "tree_count " + std::to_string(info.tree_count) + " but " +
           std::to_string(snapshot.trees.size()) + " trees at version " +
           std::to_string(info.version);
  }
  double max_x = -1e300;
  for (const TreeRecord& tree : snapshot.trees) {
    max_x = std::max(max_x, tree.x);
    if (tree.attributes.at("version") != std::to_string(info.version)) {
      return "tree of version " + tree.attributes.at("version") + " in a snapshot of version " +
             std::to_string(info.version);
    }
  }
  if (!snapshot.trees.empty() && (!info.extent || info.extent->max_x != max_x)) {
    return "extent does not match the trees at version " + std::to_string(info.version);
  }
  return "";
}

// `writes` and `reads` may be one store or two on the same database (two replicas).
void RunConcurrentReadersAndWriter(MapStore& store, MapStore& reader_store) {
  store.CreateMap("busy", "", "");
  constexpr int kWrites = 100;
  constexpr int kReaders = 3;
  std::atomic<bool> done{false};
  std::mutex failures_mutex;
  std::vector<std::string> failures;
  std::atomic<int64_t> reads{0};
  const auto fail = [&](const std::string& what) {
    std::lock_guard<std::mutex> lock(failures_mutex);
    failures.push_back(what);
  };
  const auto failures_count = [&] {
    std::lock_guard<std::mutex> lock(failures_mutex);
    return failures.size();
  };

  std::thread writer([&] {
    try {
      while (reads < kReaders && failures_count() == 0) std::this_thread::yield();  // overlap
      for (int i = 0; i < kWrites; ++i) {
        // Version i + 2 replaces all trees with a batch whose size changes every time.
        const std::string version = std::to_string(i + 2);
        std::vector<TreeRecord> trees;
        for (int k = 0; k < 1 + (i * 37) % 700; ++k) {
          TreeRecord tree = Tree(std::nullopt, k, i);
          tree.attributes["version"] = version;
          trees.push_back(tree);
        }
        store.WriteTrees("busy", trees, WriteMode::kReplace);
        store.CreateMap("tmp" + std::to_string(i), "", "");  // other writes in between
        if (i % 2 == 1) store.DeleteMap("tmp" + std::to_string(i - 1));
      }
    } catch (const std::exception& e) {
      fail(std::string("writer: ") + e.what());
    }
    done = true;
  });
  std::vector<std::thread> readers;
  for (int r = 0; r < kReaders; ++r) {
    readers.emplace_back([&] {
      try {
        while (!done) {
          const std::string problem = CheckSnapshot(reader_store.ReadMap("busy"));
          if (!problem.empty()) fail(problem);
          const MapInfo info = reader_store.GetMap("busy");
          if (info.version < 1) fail("bad version");
          reader_store.TreesInBox("busy", Extent{0, 0, 100, 100});
          reader_store.ListMaps();
          ++reads;
        }
      } catch (const std::exception& e) {
        fail(std::string("reader: ") + e.what());
      }
    });
  }
  writer.join();
  for (std::thread& reader : readers) reader.join();
  EXPECT_TRUE(failures.empty()) << failures.size() << " failures, first: " << failures.front();
  EXPECT_GT(reads.load(), 0);
  EXPECT_EQ(store.GetMap("busy").version, kWrites + 1);
  EXPECT_EQ(CheckSnapshot(store.ReadMap("busy")), "");
}

class ConcurrencyTest : public ::testing::TestWithParam<Backend> {};
INSTANTIATE_TEST_SUITE_P(Backends, ConcurrencyTest,
                         ::testing::Values(Backend::kSqlite, Backend::kSqliteFile,
                                           Backend::kPostgres),
                         BackendName);

TEST_P(ConcurrencyTest, ConcurrentReadersSeeConsistentSnapshots) {
  TestStore store(GetParam());
  RunConcurrentReadersAndWriter(*store, *store);
}

// Two stores on one database, as two forestmapd replicas: readers of one see whole versions
// that the other writes.
class ReplicaTest : public ::testing::TestWithParam<Backend> {};
INSTANTIATE_TEST_SUITE_P(Backends, ReplicaTest, kSharedBackends, BackendName);

TEST_P(ReplicaTest, AnotherReplicaSeesConsistentSnapshots) {
  TestStore store(GetParam());
  const std::unique_ptr<MapStore> replica = store.Another();
  RunConcurrentReadersAndWriter(*store, *replica);
}

}  // namespace
}  // namespace forestmap::storage
