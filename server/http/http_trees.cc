#include "server/http/http_trees.h"

// clang-format off
#include "server/http/httplib_include.h"
// clang-format on

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <utility>
#include <vector>

#include "server/app/tree_pages.h"

namespace forestmap::server {
namespace {

void AppendTree(std::string& out, const storage::TreeRecord& tree) {
  out += '[';
  AppendJsonNumber(out, tree.x);
  out += ',';
  AppendJsonNumber(out, tree.y);
  out += ',';
  if (tree.dbh) {
    AppendJsonNumber(out, *tree.dbh);
  } else {
    out += "null";
  }
  out += tree.status == storage::TreeStatus::kConfirmed ? ",true," : ",false,";
  out += std::to_string(*tree.id);
  out += ']';
}

// Where a streamed answer is: what it reads next. Lives as long as the response.
struct TreeStream {
  TreeStream(storage::MapStore& store, const storage::MapInfo& info, std::string json,
             std::optional<storage::Extent> box, int64_t page_trees)
      : pages(store, info, page_trees, std::move(box)), map_json(std::move(json)) {}

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

void AppendJsonNumber(std::string& out, double value) {
  if (!std::isfinite(value)) {
    out += "null";
    return;
  }
  char buffer[32];
  const std::to_chars_result end = std::to_chars(buffer, buffer + sizeof(buffer), value);
  out.append(buffer, end.ptr);
}

void ReplyTreesStreamed(httplib::Response& response, storage::MapStore& store,
                        const storage::MapInfo& info, const std::string& map_json,
                        std::optional<storage::Extent> box, int64_t page_trees) {
  auto stream = std::make_shared<TreeStream>(store, info, map_json, std::move(box), page_trees);
  response.set_chunked_content_provider(
      "application/json",
      [stream](size_t /*offset*/, httplib::DataSink& sink) { return stream->WriteNext(sink); });
}

storage::Extent ParseBox(const std::string& name, const std::string& text) {
  std::array<double, 4> v{};
  const char* at = text.data();
  const char* const end = text.data() + text.size();
  for (size_t i = 0; i < v.size(); ++i) {
    const auto [next, error] = std::from_chars(at, end, v[i]);
    const bool last = i + 1 == v.size();
    if (error != std::errc() || !std::isfinite(v[i]) || (last ? next != end : *next != ',')) {
      throw std::invalid_argument(name + "=" + text + ": give minx,miny,maxx,maxy (4 numbers)");
    }
    at = next + 1;
  }
  if (v[0] > v[2] || v[1] > v[3]) {
    throw std::invalid_argument(name + "=" + text + ": the minimum is above the maximum");
  }
  return {v[0], v[1], v[2], v[3]};
}

TreeDensity DensityOf(storage::MapStore& store, const storage::MapInfo& info) {
  TreeDensity density;
  if (!info.extent) return density;
  const storage::Extent& e = *info.extent;
  density.min_x = e.min_x;
  density.min_y = e.min_y;
  density.cell_m = std::max(std::max(e.max_x - e.min_x, e.max_y - e.min_y) / kDensityCells, 1e-3);
  const auto cells = [&](double length) {
    return std::clamp(static_cast<int>(std::floor(length / density.cell_m)) + 1, 1,
                      kDensityCells + 1);
  };
  density.columns = cells(e.max_x - e.min_x);
  density.rows = cells(e.max_y - e.min_y);
  density.counts.assign(static_cast<size_t>(density.columns) * density.rows, 0);
  constexpr int64_t kPage = 50'000;
  TreePages pages(store, info, kPage);
  while (!pages.done()) {
    for (const storage::TreeRecord& tree : pages.Next()) {
      const int column = std::clamp(static_cast<int>((tree.x - density.min_x) / density.cell_m), 0,
                                    density.columns - 1);
      const int row = std::clamp(static_cast<int>((tree.y - density.min_y) / density.cell_m), 0,
                                 density.rows - 1);
      ++density.counts[static_cast<size_t>(row) * density.columns + column];
    }
  }
  return density;
}

}  // namespace forestmap::server
