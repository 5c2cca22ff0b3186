#include "server/http/http_trees.h"

// clang-format off
#include <httplib.h>
// clang-format on

#include <charconv>
#include <cmath>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "storage/staged_writes.h"

namespace forestmap::server {
namespace {

// Shortest text that reads back as `value` (JSON has no NaN or infinity: null).
void AppendNumber(std::string& out, double value) {
  if (!std::isfinite(value)) {
    out += "null";
    return;
  }
  char buffer[32];
  const std::to_chars_result end = std::to_chars(buffer, buffer + sizeof(buffer), value);
  out.append(buffer, end.ptr);
}

void AppendTree(std::string& out, const storage::TreeRecord& tree) {
  out += '[';
  AppendNumber(out, tree.x);
  out += ',';
  AppendNumber(out, tree.y);
  out += ',';
  if (tree.dbh) {
    AppendNumber(out, *tree.dbh);
  } else {
    out += "null";
  }
  out += tree.status == storage::TreeStatus::kConfirmed ? ",true]" : ",false]";
}

// Where a streamed answer is: what it reads next. Lives as long as the response.
struct TreeStream {
  TreeStream(storage::MapStore& s, storage::MapInfo i, std::string json, int64_t trees)
      : store(s), info(std::move(i)), map_json(std::move(json)), page_trees(trees) {}

  storage::MapStore& store;
  storage::MapInfo info;
  std::string map_json;
  int64_t page_trees = kHttpTreesPage;
  bool opened = false;    // the opening {"map": ..., "trees": [ is written
  bool any_tree = false;  // a tree is written (the next one follows a comma)
  std::optional<int64_t> after_id;
  std::string text;  // the chunk being written (its capacity is reused)

  // Writes the next page to `sink`; false: the store failed or the client left.
  bool WriteNext(httplib::DataSink& sink) {
    text.clear();
    if (!opened) text = "{\"map\":" + map_json + ",\"trees\":[";
    opened = true;
    storage::TreePageQuery query;
    query.version = info.version;
    query.created_unix_ms = info.created_unix_ms;
    query.after_id = after_id;
    query.limit = page_trees;
    std::vector<storage::TreeRecord> page;
    try {
      page = store.ReadTreesPage(info.name, query);
    } catch (const std::exception&) {
      return false;  // deleted or pruned meanwhile: the client sees a cut answer
    }
    for (const storage::TreeRecord& tree : page) {
      if (any_tree) text += ',';
      AppendTree(text, tree);
      any_tree = true;
    }
    if (!page.empty()) after_id = page.back().id;
    const bool last = static_cast<int64_t>(page.size()) < page_trees;
    if (last) text += "]}";
    if (!sink.write(text.data(), text.size())) return false;
    if (last) sink.done();
    return true;
  }
};

}  // namespace

void ReplyTreesStreamed(httplib::Response& response, storage::MapStore& store,
                        const storage::MapInfo& info, const std::string& map_json,
                        int64_t page_trees) {
  auto stream = std::make_shared<TreeStream>(store, info, map_json, page_trees);
  response.set_chunked_content_provider(
      "application/json",
      [stream](size_t /*offset*/, httplib::DataSink& sink) { return stream->WriteNext(sink); });
}

}  // namespace forestmap::server
