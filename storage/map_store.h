#pragma once
// Persistent storage of forest maps.

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace forestmap::storage {

// The one error type of storage/. `code` tells the server which gRPC status to answer with.
class StorageError : public std::runtime_error {
 public:
  enum class Code { kNotFound, kAlreadyExists, kInvalidArgument, kConflict, kInternal };
  StorageError(Code code, const std::string& message) : std::runtime_error(message), code_(code) {}
  Code code() const { return code_; }

 private:
  Code code_;
};

struct Extent {
  double min_x = 0, min_y = 0, max_x = 0, max_y = 0;  // m, map frame
};

struct MapInfo {
  std::string name;
  std::string description;
  std::string crs;  // empty when unknown
  int64_t version = 0;  // 1 at creation, +1 on every change
  int64_t tree_count = 0;
  std::optional<Extent> extent;  // unset for an empty map
  int64_t created_unix_ms = 0;
  int64_t updated_unix_ms = 0;
};

// One stored tree. Unknown z / dbh are std::nullopt (NULL in SQL).
struct TreeRecord {
  std::optional<int64_t> id;  // always set when read; on write, nullopt asks the store for one
  double x = 0, y = 0;  // m
  std::optional<double> z;    // m
  std::optional<double> dbh;  // m
  std::map<std::string, std::string> attributes;

  bool operator==(const TreeRecord&) const = default;
};

// A consistent snapshot of a map: its info and all its trees (sorted by id), read together.
struct MapSnapshot {
  MapInfo info;
  std::vector<TreeRecord> trees;
};

enum class WriteMode {
  kAppend,   // add trees; an id already in the map is an error
  kReplace,  // the map's trees become exactly these
};

// Thread-safety: every method may be called from many threads at once. Each write is one
// transaction: it is applied whole or not at all. Errors are thrown as StorageError.
class MapStore {
 public:
  virtual ~MapStore() = default;

  // Throws kAlreadyExists if the name is taken, kInvalidArgument for an invalid name.
  virtual MapInfo CreateMap(const std::string& name, const std::string& description,
                            const std::string& crs) = 0;
  virtual std::vector<MapInfo> ListMaps() = 0;  // sorted by name
  virtual MapInfo GetMap(const std::string& name) = 0;  // kNotFound
  virtual void DeleteMap(const std::string& name) = 0;  // kNotFound

  // Writes trees in one transaction and bumps the version. Trees without an id get the next
  // free ids (above every id in the map and in `trees`), in order. Duplicate ids (within `trees`
  // or, in kAppend, against the map) -> kInvalidArgument naming the id; kNotFound for the map.
  virtual MapInfo WriteTrees(const std::string& name, const std::vector<TreeRecord>& trees,
                             WriteMode mode) = 0;

  // All trees of a map with the info of the same version.
  virtual MapSnapshot ReadMap(const std::string& name) = 0;

  // Trees whose (x, y) lies inside the box (inclusive), by id, through the spatial index.
  virtual std::vector<TreeRecord> TreesInBox(const std::string& name, const Extent& box) = 0;
};

// Valid map names: 1..128 characters of [A-Za-z0-9_.-]. Returns an error message or "".
std::string ValidateMapName(const std::string& name);

}  // namespace forestmap::storage
