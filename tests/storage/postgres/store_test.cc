// PostgresMapStore specifics (the shared suite runs on it through store_backends.h): reopening,
// schema versions, errors naming the server, deletion, and writes through several stores on one
// database (forestmapd replicas) that serialize per map without losing an update.
#include "storage/postgres/store.h"

#include <gtest/gtest.h>

#include <string>
#include <thread>
#include <vector>

#include "storage/postgres/connection.h"
#include "tests/pg_fixture.h"
#include "tests/storage/store_backends.h"
#include "tests/storage/store_test_util.h"

namespace forestmap::storage {
namespace {

using Code = StorageError::Code;

TEST(PostgresMapStore, ReopeningKeepsDataAndSchemaVersion) {
  testing::TestDatabase database;
  TreeRecord tree = Tree(3, 1.5, -2.25);
  tree.z = 0.125;
  tree.attributes = {{"species", "Pinus sylvestris"}};
  tree.null_attributes = {"LI"};  // a survey column unknown for this tree
  {
    PostgresMapStore store(database.url());
    store.CreateMap("plot", "a plot", "EPSG:3067");
    store.WriteTrees("plot", {tree, Tree(4, 0, 0)}, WriteMode::kAppend);
  }
  for (int reopen = 0; reopen < 2; ++reopen) {  // migrations must not run again
    PostgresMapStore store(database.url());
    const MapSnapshot snapshot = store.ReadMap("plot");
    EXPECT_EQ(snapshot.info.description, "a plot");
    EXPECT_EQ(snapshot.info.version, 2);
    EXPECT_EQ(snapshot.trees, (std::vector<TreeRecord>{tree, Tree(4, 0, 0)}));
  }
  pg::Connection raw(database.url());
  EXPECT_EQ(raw.Exec("SELECT version FROM forestmap_schema").Int64(0, 0),
            PostgresMapStore::kSchemaVersion);
}

TEST(PostgresMapStore, RefusesADatabaseFromANewerVersion) {
  testing::TestDatabase database;
  { PostgresMapStore store(database.url()); }
  pg::Connection raw(database.url());
  raw.ExecScript("UPDATE forestmap_schema SET version = 99");
  try {
    PostgresMapStore store(database.url());
    ADD_FAILURE() << "a newer schema was accepted";
  } catch (const StorageError& e) {
    EXPECT_NE(std::string(e.what()).find("schema version 99"), std::string::npos) << e.what();
  }
}

TEST(PostgresMapStore, AnUnreachableServerIsNamedInTheError) {
  // Port 1 on loopback: nothing listens there.
  try {
    PostgresMapStore store("postgresql://someone:secret@127.0.0.1:1/maps?connect_timeout=2");
    ADD_FAILURE() << "connected to nothing";
  } catch (const StorageError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("127.0.0.1:1/maps"), std::string::npos) << message;
    EXPECT_EQ(message.find("secret"), std::string::npos) << "password leaked: " << message;
  }
}

TEST(PostgresMapStore, DeletingAMapRemovesItsRowsAndFreesTheName) {
  testing::TestDatabase database;
  PostgresMapStore store(database.url());
  std::vector<TreeRecord> trees;
  for (int64_t id = 1; id <= 500; ++id) trees.push_back(Tree(id, id * 0.5, -id * 0.25));
  store.CreateMap("gone", "", "");
  store.CreateMap("kept", "", "");
  store.WriteTrees("gone", trees, WriteMode::kAppend);
  store.WriteTrees("kept", {trees.begin(), trees.begin() + 10}, WriteMode::kAppend);
  store.DeleteMap("gone");
  pg::Connection raw(database.url());
  EXPECT_EQ(raw.Exec("SELECT COUNT(*) FROM trees").Int64(0, 0), 10);
  EXPECT_EQ(raw.Exec("SELECT COUNT(*) FROM map_versions").Int64(0, 0), 2);
  store.CreateMap("gone", "", "");
  EXPECT_TRUE(store.ReadMap("gone").trees.empty());
  EXPECT_EQ(store.TreesInBox("kept", Extent{-1e9, -1e9, 1e9, 1e9}).size(), 10u);
}

// Three stores on one database (three replicas), four threads each: every merge reads tree 1's
// counter and writes it + 1. Merges of one map serialize across the stores (advisory lock), so
// no increment is lost and every merge makes exactly one version.
TEST(PostgresMapStore, MergesThroughSeveralReplicasSerializePerMap) {
  testing::TestDatabase database;
  constexpr int kReplicas = 3, kThreads = 4, kMerges = 15;
  std::vector<std::unique_ptr<PostgresMapStore>> replicas;
  for (int r = 0; r < kReplicas; ++r) {
    replicas.push_back(std::make_unique<PostgresMapStore>(database.url()));
  }
  replicas[0]->CreateMap("m", "", "");
  replicas[0]->CreateMap("other", "", "");
  TreeRecord counter = Tree(1, 0, 0);
  counter.observations = 0;
  replicas[0]->WriteTrees("m", {counter}, WriteMode::kAppend);
  std::vector<std::thread> threads;
  std::atomic<int> failures{0};
  for (int t = 0; t < kReplicas * kThreads; ++t) {
    threads.emplace_back([&, t] {
      MapStore& store = *replicas[t % kReplicas];
      for (int i = 0; i < kMerges; ++i) {
        try {
          store.Merge("m", MergeNote{VersionKind::kObserve, std::to_string(t), {}},
                      [](MergeReader& reader) {
                        const int64_t ids[] = {1};
                        TreeRecord tree = reader.TreesById(ids).at(0);
                        tree.observations += 1;
                        MapChanges changes;
                        changes.put_trees.push_back(tree);
                        return changes;
                      });
          store.WriteTrees("other", {}, WriteMode::kAppend);  // other maps do not wait
        } catch (const std::exception& e) {
          ++failures;
          ADD_FAILURE() << e.what();
        }
      }
    });
  }
  for (std::thread& thread : threads) thread.join();
  EXPECT_EQ(failures.load(), 0);
  constexpr int kTotal = kReplicas * kThreads * kMerges;
  const MapSnapshot now = replicas[1]->ReadMap("m");
  EXPECT_EQ(now.trees.at(0).observations, kTotal);
  EXPECT_EQ(now.info.version, 2 + kTotal);
  EXPECT_EQ(replicas[2]->ListVersions("m", 0).size(), static_cast<size_t>(2 + kTotal));
}

}  // namespace
}  // namespace forestmap::storage
