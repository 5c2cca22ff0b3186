#include "server/app/readiness.h"

#include <algorithm>
#include <exception>
#include <future>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "server/app/errors.h"
#include "storage/map_store.h"

namespace forestmap::server {

void ReadinessOptions::Check() const {
  if (interval.count() <= 0) throw std::invalid_argument("ReadinessOptions.interval must be > 0");
  if (probe_timeout.count() <= 0) {
    throw std::invalid_argument("ReadinessOptions.probe_timeout must be > 0");
  }
  for (const std::string& name : preload) {
    if (name.empty()) throw std::invalid_argument("ReadinessOptions.preload: empty map name");
  }
}

void ParsePreload(const std::string& text, ReadinessOptions& options) {
  options.preload_all = text == "all";
  options.preload.clear();
  if (options.preload_all) return;
  std::stringstream list(text);
  for (std::string name; std::getline(list, name, ',');) {
    if (name.empty()) throw std::invalid_argument("--preload: empty map name in '" + text + "'");
    options.preload.push_back(name);
  }
  if (options.preload.empty()) throw std::invalid_argument("--preload: no map named");
}

std::string MapHealthName(const std::string& map_name) { return "map/" + map_name; }

Readiness::Readiness(storage::MapStore& store, MapIndexCache& cache, ReadinessOptions options,
                     Publish publish)
    : store_(store), cache_(cache), options_(std::move(options)), publish_(std::move(publish)) {
  options_.Check();
  state_.reason = "starting";
  publish_("", false, state_.reason);
  thread_ = std::thread([this] { Loop(); });
}

Readiness::~Readiness() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

Readiness::State Readiness::state() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return state_;
}

void Readiness::Loop() {
  std::unique_lock<std::mutex> lock(mutex_);
  while (!stopping_) {
    lock.unlock();
    Round();
    lock.lock();
    wake_.wait_for(lock, options_.interval, [this] { return stopping_; });
  }
}

void Readiness::Round() {
  // The probe runs on its own thread so that a database that does not answer (a network
  // partition, a lock held) turns the server NOT ready after probe_timeout, not never.
  auto probe = std::async(std::launch::async, [this] { return store_.ListMaps(); });
  if (probe.wait_for(options_.probe_timeout) == std::future_status::timeout) {
    Set(false, "the database did not answer within " +
                   std::to_string(options_.probe_timeout.count()) + " ms");
  }
  std::vector<storage::MapInfo> maps;
  try {
    maps = probe.get();
  } catch (const std::exception& e) {
    Set(false, std::string("database unreachable: ") + e.what());
    for (const std::string& name : published_maps_) SetMap(name, false);
    return;
  }
  std::string reason;
  const bool warm = WarmPreloaded(maps, reason);
  bool ready = warm;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    warmed_once_ = warmed_once_ || warm;
    ready = warmed_once_;
  }
  Set(ready, ready ? "" : reason);
}

bool Readiness::WarmPreloaded(const std::vector<storage::MapInfo>& maps, std::string& reason) {
  std::vector<std::string> names;
  if (options_.preload_all) {
    for (const storage::MapInfo& map : maps) {
      if (map.confirmed_count > 0) names.push_back(map.name);
    }
    // The cache keeps max_entries indexes: warming more would evict the first ones again.
    names.resize(std::min<size_t>(names.size(), cache_.max_entries()));
  } else {
    names = options_.preload;
  }
  bool all_warm = true;
  for (const std::string& name : names) {
    const bool exists = std::any_of(maps.begin(), maps.end(),
                                    [&](const storage::MapInfo& map) { return map.name == name; });
    bool warm = false;
    if (exists) {
      try {
        cache_.Warm(name);
        warm = true;
      } catch (const ServiceError&) {
        // No confirmed trees, or trees that cannot be indexed: nothing to warm, nothing to wait
        // for (a query answers FAILED_PRECONDITION at once).
      } catch (const storage::StorageError& e) {
        if (e.code() != storage::StorageError::Code::kNotFound) {  // deleted meanwhile: fine
          all_warm = false;
          if (reason.empty()) reason = "warming the index of map '" + name + "': " + e.what();
        }
      } catch (const std::exception& e) {
        all_warm = false;
        if (reason.empty()) reason = "warming the index of map '" + name + "': " + e.what();
      }
    }
    SetMap(name, warm);
  }
  // Maps no longer preloaded (deleted, or beyond the cache's size now) stop answering SERVING.
  for (const std::string& name : published_maps_) {
    if (std::find(names.begin(), names.end(), name) == names.end()) SetMap(name, false);
  }
  published_maps_ = names;
  return all_warm;
}

void Readiness::Set(bool ready, const std::string& reason) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    state_.ready = ready;
    state_.reason = reason;
  }
  publish_("", ready, reason);
}

void Readiness::SetMap(const std::string& name, bool serving) {
  publish_(MapHealthName(name), serving, serving ? "" : "index not warm");
}

}  // namespace forestmap::server
