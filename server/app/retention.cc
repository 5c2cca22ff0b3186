#include "server/app/retention.h"

#include <exception>
#include <stdexcept>
#include <utility>

namespace forestmap::server {

void CheckKeep(int64_t keep) {
  if (keep < 1) {
    throw ValidationError("keep", " is " + std::to_string(keep) +
                                      "; at least the current version must stay (keep >= 1)");
  }
}

storage::PruneResult PruneHistory(storage::MapStore& store, const std::string& map, int64_t keep) {
  CheckKeep(keep);
  return store.PruneVersions(map, keep);
}

RetentionPolicy::RetentionPolicy(storage::MapStore& store, int64_t keep_versions,
                                 FaultReport report)
    : store_(store), keep_versions_(keep_versions), report_(std::move(report)) {
  if (!report_) throw std::invalid_argument("RetentionPolicy needs a report for its failures");
  if (keep_versions < 0) {
    throw std::invalid_argument("RetentionPolicy: keep_versions must be >= 0 (0 keeps all)");
  }
}

bool RetentionPolicy::AfterWrite(const std::string& map) const {
  if (keep_versions_ == 0) return true;
  std::string why;
  try {
    PruneHistory(store_, map, keep_versions_);
    return true;
  } catch (const std::exception& e) {
    why = e.what();
  } catch (...) {
    why = "an exception that is not a std::exception";
  }
  report_("retention of map \"" + map + "\" failed (the write stands): " + why);
  return false;
}

}  // namespace forestmap::server
