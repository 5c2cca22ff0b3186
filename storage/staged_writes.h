#pragma once
// Bounded-memory writes and reads of whole maps: uploads staged in the database and
// exports read page by page. Both are MapStore methods (storage/map_store.h); the types live here.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "storage/map_store.h"

namespace forestmap::storage {

// What an upload does when it commits.
struct UploadPlan {
  WriteMode mode = WriteMode::kAppend;
  // Set: the upload creates the map (which must not exist yet) in the same transaction that
  // commits its trees, so an upload that never commits leaves no map behind.
  bool create_map = false;
  std::string description;  // of the created map
  std::string crs;          // of the created map (canonical form, as for CreateMap)
  // Set: the map's survey boundary from the new version on (an empty one removes it); a changed
  // boundary alone makes a new version. Unset: the map keeps its boundary.
  std::optional<Boundary> boundary;
  // The attribute columns of the uploaded file, in its order (MapSnapshot::attribute_columns):
  // appended, the new ones follow the map's; replacing, they are the map's order. Empty: the
  // map keeps its order. Recorded with a version the upload makes; alone, it makes none.
  std::vector<std::string> attribute_columns;
};

// An upload of any size in bounded memory. Append stages trees in the database in its own short
// transaction (rows no read sees, so other writers, also of other maps, go on between chunks);
// Commit makes them the map's new version in one last transaction (and creates the map when the
// plan says so), honouring the thread's WriteRequest (storage/write_request.h). An upload that is
// destroyed without a successful Commit removes its staged rows (and the map it was to create);
// rows of an upload whose process died are removed when a store opens the database.
// Errors name trees by their index in the whole upload ("trees[k]"). Not thread-safe: one thread
// at a time per upload (different uploads may run on many threads).
class TreeUpload {
 public:
  virtual ~TreeUpload() = default;
  // Stages the next trees of the upload. Ids: explicit ones are kept; a tree without one gets the
  // next free id above every id of the map (append) and every explicit id sent so far, in order.
  // kInvalidArgument for a duplicate id within the upload (naming both indices), a non-finite
  // coordinate; kNotFound when the map was deleted meanwhile.
  virtual void Append(const std::vector<TreeRecord>& trees) = 0;
  // The map after the upload. kInvalidArgument for an appended id already in the map. After a
  // failed Append or Commit the upload is aborted (its staged rows are gone).
  virtual MapInfo Commit() = 0;
  virtual int64_t staged() const = 0;  // trees appended so far
};

// One page of an export (MapStore::ReadTreesPage).
struct TreePageQuery {
  int64_t version = 0;              // the version to read (>= 1)
  int64_t created_unix_ms = 0;      // the map's creation time seen by the first page (0: any)
  std::optional<int64_t> after_id;  // trees with a larger id only (unset: from the first)
  int64_t limit = 5000;             // trees at most (>= 1)
  std::optional<Extent> box;        // only trees inside (inclusive)
};

// The store-independent upload: holds the trees in memory and writes them with CreateMap and
// WriteTrees at Commit (not atomic for create_map). The MapStore default for stores that
// cannot stage; SqliteMapStore and PostgresMapStore stage in their databases.
std::unique_ptr<TreeUpload> MemoryUpload(MapStore& store, const std::string& name,
                                         const UploadPlan& plan);

// The trees of `query` cut from a whole ReadMapVersion (the MapStore default).
std::vector<TreeRecord> PageOfSnapshot(MapStore& store, const std::string& name,
                                       const TreePageQuery& query);

}  // namespace forestmap::storage
