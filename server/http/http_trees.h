#pragma once
// GET /api/maps/NAME/trees of the web page (server/http/http_page.h), streamed: the answer is
// written in HTTP chunks of at most kHttpTreesPage trees, each read as the gRPC ExportTrees reads
// them (server/app/tree_pages.h), so a request holds one page in memory whatever the map's size
// (a whole JSON document of a 300,000-tree map took ~100 MB per request, kept by the malloc arena
// of each HTTP thread: tests/bench/http_trees_memory.sh).

#include <cstdint>
#include <string>

#include "storage/map_store.h"

namespace httplib {
struct Response;
}  // namespace httplib

namespace forestmap::server {

inline constexpr int64_t kHttpTreesPage = 4'096;  // trees read and sent per chunk, at most

// Answers `response` with {"map": <map_json>, "trees": [[x, y, dbh|null, confirmed], ...]}: the
// trees of version `info.version` of map `info.name`, streamed page by page. If the version
// disappears meanwhile (deleted, pruned) the connection is closed before the closing "]}".
void ReplyTreesStreamed(httplib::Response& response, storage::MapStore& store,
                        const storage::MapInfo& info, const std::string& map_json,
                        int64_t page_trees = kHttpTreesPage);

}  // namespace forestmap::server
