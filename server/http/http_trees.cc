#include "server/http/http_trees.h"

// clang-format off
#include <httplib.h>
// clang-format on

#include <charconv>
#include <cmath>
#include <memory>
#include <utility>
#include <vector>

#include "server/app/tree_pages.h"

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
  TreeStream(storage::MapStore& store, const storage::MapInfo& info, std::string json,
             int64_t page_trees)
      : pages(store, info, page_trees), map_json(std::move(json)) {}

  TreePages pages;
  std::string map_json;
  bool opened = false;    // the opening {"map": ..., "trees": [ is written
  bool any_tree = false;  // a tree is written (the next one follows a comma)
  std::string text;       // the chunk being written (its capacity is reused)

  // Writes the next page to `sink`; false: the store failed or the client left.
  bool WriteNext(httplib::DataSink& sink) {
    text.clear();
    if (!opened) text = "{\"map\":" + map_json + ",\"trees\":[";
    opened = true;
    std::vector<storage::TreeRecord> page;
    try {
      page = pages.Next();
    } catch (const std::exception&) {
      return false;  // deleted or pruned meanwhile: the client sees a cut answer
    }
    for (const storage::TreeRecord& tree : page) {
      if (any_tree) text += ',';
      AppendTree(text, tree);
      any_tree = true;
    }
    const bool last = pages.done();
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
