#pragma once
// Whether the server can answer now, told truthfully to load balancers: forestmapd's gRPC health
// service (grpc.health.v1.Health) and the metrics port's /readyz follow it.
//
// A background thread runs a round every `interval`: it asks the database for the list of maps
// (a round that fails, or takes longer than `probe_timeout`, makes the server NOT ready: every
// RPC needs the database), then warms the relocalization index of every preloaded map
// (MapIndexCache::Warm: built once per map version, so a map that was written to is rebuilt in
// the next round instead of by the next drone's query). The server becomes ready after the
// first round that reached the database and warmed every preloaded map, and stays ready while
// the database answers. Each preloaded map also has its own status, SERVING while its index is
// warm for its current version: health service name "map/NAME".
//
// Thread-safety: state() may be called from any thread. The callback is called from the
// round's thread (and from the constructor).

#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "server/app/map_index_cache.h"
#include "storage/map_store.h"

namespace forestmap::server {

struct ReadinessOptions {
  std::chrono::milliseconds interval{2000};       // between rounds
  std::chrono::milliseconds probe_timeout{5000};  // a slower database counts as unreachable
  bool preload_all = false;                       // every map (up to the index cache's size)
  std::vector<std::string> preload;               // these maps
  void Check() const;                             // throws std::invalid_argument
};

// "all" -> preload_all; "a,b,c" -> those names. Throws std::invalid_argument for an empty name.
void ParsePreload(const std::string& text, ReadinessOptions& options);

// The health service name of a preloaded map's own status.
std::string MapHealthName(const std::string& map_name);

class Readiness {
 public:
  struct State {
    bool ready = false;
    std::string reason;  // why not ready ("" when ready)
  };
  // (health service name, serving, why not): "" is the whole server.
  using Publish =
      std::function<void(const std::string& service, bool serving, const std::string& reason)>;

  // Starts the rounds; the first one runs at once. `store` and `cache` must outlive this.
  Readiness(storage::MapStore& store, MapIndexCache& cache, ReadinessOptions options,
            Publish publish);
  ~Readiness();  // stops the thread (waits for a round in progress)
  Readiness(const Readiness&) = delete;
  Readiness& operator=(const Readiness&) = delete;

  State state() const;

 private:
  void Loop();
  void Round();
  // Warms the preloaded maps among `maps`; false with a reason when one could not be warmed.
  bool WarmPreloaded(const std::vector<storage::MapInfo>& maps, std::string& reason);
  void Set(bool ready, const std::string& reason);
  void SetMap(const std::string& name, bool serving);

  storage::MapStore& store_;
  MapIndexCache& cache_;
  const ReadinessOptions options_;
  const Publish publish_;
  mutable std::mutex mutex_;
  State state_;
  bool warmed_once_ = false;  // every preloaded map was warm once: readiness no longer waits
  std::vector<std::string> published_maps_;  // names given a map status (to clear on removal)
  std::condition_variable wake_;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace forestmap::server
