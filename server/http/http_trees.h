#pragma once
// GET /api/maps/NAME/trees of the web page (server/http/http_page.h), streamed: the answer is
// written in HTTP chunks of at most kHttpTreesPage trees, each read as the gRPC ExportTrees reads
// them (server/app/tree_pages.h), so a request holds one page in memory whatever the map's size
// (a whole JSON document of a 300,000-tree map took ~100 MB per request, kept by the malloc arena
// of each HTTP thread: tests/bench/http_trees_memory.sh).

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "storage/map_store.h"

namespace httplib {
struct Response;
}  // namespace httplib

namespace forestmap::server {

inline constexpr int64_t kHttpTreesPage = 4'096;  // trees read and sent per chunk, at most

// Appends the shortest text that reads back as `value` (JSON has no NaN or infinity: null).
void AppendJsonNumber(std::string& out, double value);

// Answers `response` with {"map": <map_json>, "trees": [[x, y, dbh|null, confirmed, id], ...]}:
// the trees of version `info.version` of map `info.name` (those inside `box` when set), streamed
// page by page. If the version disappears meanwhile (deleted, pruned) the connection is closed
// before the closing "]}".
void ReplyTreesStreamed(httplib::Response& response, storage::MapStore& store,
                        const storage::MapInfo& info, const std::string& map_json,
                        std::optional<storage::Extent> box = std::nullopt,
                        int64_t page_trees = kHttpTreesPage);

// A box parameter "min_x,min_y,max_x,max_y" (4 finite numbers, min <= max). Throws
// std::invalid_argument "NAME=TEXT: ..." for anything else.
storage::Extent ParseBox(const std::string& name, const std::string& text);

// How many trees of version `info.version` lie in each cell of a grid over the map's extent,
// for the page's view of a map too large to draw tree by tree: cells of `cell_m` metres (the
// extent's longer side / kDensityCells), counts row by row from the south-west corner. Reads the
// map page by page (bounded memory).
inline constexpr int kDensityCells = 256;  // along the extent's longer side
struct TreeDensity {
  double min_x = 0, min_y = 0, cell_m = 1;
  int columns = 0, rows = 0;
  std::vector<uint32_t> counts;  // columns * rows, row-major from min_y
};
TreeDensity DensityOf(storage::MapStore& store, const storage::MapInfo& info);

}  // namespace forestmap::server
