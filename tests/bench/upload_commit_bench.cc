// Issue 15, writers per map, and the store's hot paths on either backend. Stages TREES trees in
// chunks of 10,000 (as the server does), then times Commit for: an upload that creates its map
// (`forestmap map create NAME --trees`), an append to an existing map and a replace of it. Then
// times WriteTrees of all TREES trees in one call (kReplace), a full export of the map by
// ReadTreesPage pages (5,000 trees each, as the server reads them) and 100 TreesInBox queries of
// ~10,000 trees each. Prints one JSON line per kind. The store is a new SQLite file in DIR
// (removed at the end), or the PostgreSQL database DB (a postgresql:// URI; its maps of the
// bench are deleted at the end).
//   upload_commit_bench DIR [TREES=1000000] [DB]

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "storage/open_store.h"
#include "storage/staged_writes.h"

namespace {

using forestmap::storage::Extent;
using forestmap::storage::MapInfo;
using forestmap::storage::MapStore;
using forestmap::storage::TreePageQuery;
using forestmap::storage::TreeRecord;
using forestmap::storage::UploadPlan;
using forestmap::storage::WriteMode;
using Clock = std::chrono::steady_clock;

constexpr int kChunkTrees = 10'000;  // trees per Append, as the server stages them

double Ms(Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); }

std::vector<TreeRecord> Chunk(int64_t first, int count) {
  std::vector<TreeRecord> trees(static_cast<size_t>(count));
  for (int i = 0; i < count; ++i) {
    const int64_t k = first + i;
    trees[static_cast<size_t>(i)].x = static_cast<double>(k % 1000) * 3.0;
    trees[static_cast<size_t>(i)].y = static_cast<double>(k / 1000) * 3.0;
    trees[static_cast<size_t>(i)].dbh = 0.25;
  }
  return trees;
}

// Stages `trees` trees into an upload of `name` with `plan`, then times its Commit.
void Run(MapStore& store, const char* kind, const std::string& name, const UploadPlan& plan,
         int64_t trees) {
  const auto start = Clock::now();
  auto upload = store.BeginUpload(name, plan);
  for (int64_t first = 0; first < trees; first += kChunkTrees) {
    upload->Append(Chunk(first, static_cast<int>(std::min<int64_t>(kChunkTrees, trees - first))));
  }
  const auto staged = Clock::now();
  const MapInfo info = upload->Commit();
  const auto done = Clock::now();
  std::printf(
      "{\"kind\":\"%s\",\"trees\":%lld,\"stage_ms\":%.0f,\"commit_ms\":%.1f,\"map_trees\":%lld}\n",
      kind, static_cast<long long>(trees), Ms(staged - start), Ms(done - staged),
      static_cast<long long>(info.tree_count));
  std::fflush(stdout);
}

// WriteTrees of `trees` trees in one call, replacing the map's trees.
void Write(MapStore& store, const std::string& name, int64_t trees) {
  const std::vector<TreeRecord> all = Chunk(0, static_cast<int>(trees));
  const auto start = Clock::now();
  const MapInfo info = store.WriteTrees(name, all, WriteMode::kReplace);
  std::printf("{\"kind\":\"write_trees\",\"trees\":%lld,\"ms\":%.0f,\"map_trees\":%lld}\n",
              static_cast<long long>(trees), Ms(Clock::now() - start),
              static_cast<long long>(info.tree_count));
  std::fflush(stdout);
}

// Reads the current version of the map page by page, as an export does.
void Export(MapStore& store, const std::string& name) {
  const auto start = Clock::now();
  TreePageQuery query;
  query.version = store.GetMap(name).version;
  int64_t read = 0, pages = 0;
  for (;;) {
    const std::vector<TreeRecord> page = store.ReadTreesPage(name, query);
    if (page.empty()) break;
    read += static_cast<int64_t>(page.size());
    ++pages;
    query.after_id = page.back().id;
  }
  std::printf("{\"kind\":\"export_pages\",\"trees\":%lld,\"pages\":%lld,\"ms\":%.0f}\n",
              static_cast<long long>(read), static_cast<long long>(pages),
              Ms(Clock::now() - start));
  std::fflush(stdout);
}

// 100 box queries of 300 m x 300 m (about 10,000 trees each) across the map.
void Boxes(MapStore& store, const std::string& name) {
  const auto start = Clock::now();
  int64_t found = 0;
  for (int q = 0; q < 100; ++q) {
    const double x = (q % 10) * 270.0, y = (q / 10) * 27.0;
    found +=
        static_cast<int64_t>(store.TreesInBox(name, Extent{x, y, x + 299.0, y + 299.0}).size());
  }
  std::printf("{\"kind\":\"trees_in_box\",\"queries\":100,\"trees\":%lld,\"ms\":%.0f}\n",
              static_cast<long long>(found), Ms(Clock::now() - start));
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: upload_commit_bench DIR [TREES=1000000] [DB]\n");
    return 2;
  }
  const std::filesystem::path dir = std::filesystem::path(argv[1]) / "upload_commit_bench";
  const int64_t trees = argc > 2 ? std::atoll(argv[2]) : 1'000'000;
  const std::string db = argc > 3 ? argv[3] : (dir / "maps.db").string();
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  {
    const std::unique_ptr<MapStore> store = forestmap::storage::OpenMapStore(db);
    UploadPlan create;
    create.create_map = true;
    Run(*store, "create", "created", create, trees);
    Run(*store, "append", "created", UploadPlan{}, trees);
    UploadPlan replace;
    replace.mode = WriteMode::kReplace;
    Run(*store, "replace", "created", replace, trees);
    Write(*store, "created", trees);
    Export(*store, "created");
    Boxes(*store, "created");
    store->DeleteMap("created");
  }
  std::filesystem::remove_all(dir);
  return 0;
}
