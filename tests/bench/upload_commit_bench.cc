// Issue 15, writers per map on SQLite: how long the last transaction of a staged upload
// (TreeUpload::Commit) holds SQLite's single writer, for uploads of TREES trees. Stages the
// trees in chunks of 10,000 (as the server does), then times Commit for: an upload that creates
// its map (`forestmap map create NAME --trees`), an append to an existing map and a replace of
// it. Prints one JSON line per kind. The database is a new file in DIR (removed at the end).
//   upload_commit_bench DIR [TREES=1000000]

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "storage/sqlite_map_store.h"
#include "storage/staged_writes.h"

namespace {

using forestmap::storage::MapInfo;
using forestmap::storage::SqliteMapStore;
using forestmap::storage::TreeRecord;
using forestmap::storage::UploadPlan;
using forestmap::storage::WriteMode;
using Clock = std::chrono::steady_clock;

constexpr int kChunkTrees = 10'000;  // trees per Append, as the server stages them

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
void Run(SqliteMapStore& store, const char* kind, const std::string& name, const UploadPlan& plan,
         int64_t trees) {
  const auto start = Clock::now();
  auto upload = store.BeginUpload(name, plan);
  for (int64_t first = 0; first < trees; first += kChunkTrees) {
    upload->Append(Chunk(first, static_cast<int>(std::min<int64_t>(kChunkTrees, trees - first))));
  }
  const auto staged = Clock::now();
  const MapInfo info = upload->Commit();
  const auto done = Clock::now();
  const auto ms = [](auto d) { return std::chrono::duration<double, std::milli>(d).count(); };
  std::printf(
      "{\"kind\":\"%s\",\"trees\":%lld,\"stage_ms\":%.0f,\"commit_ms\":%.1f,\"map_trees\":%lld}\n",
      kind, static_cast<long long>(trees), ms(staged - start), ms(done - staged),
      static_cast<long long>(info.tree_count));
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: upload_commit_bench DIR [TREES=1000000]\n");
    return 2;
  }
  const std::filesystem::path dir = std::filesystem::path(argv[1]) / "upload_commit_bench";
  const int64_t trees = argc > 2 ? std::atoll(argv[2]) : 1'000'000;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  {
    SqliteMapStore store((dir / "maps.db").string());
    UploadPlan create;
    create.create_map = true;
    Run(store, "create", "created", create, trees);
    Run(store, "append", "created", UploadPlan{}, trees);
    UploadPlan replace;
    replace.mode = WriteMode::kReplace;
    Run(store, "replace", "created", replace, trees);
  }
  std::filesystem::remove_all(dir);
  return 0;
}
