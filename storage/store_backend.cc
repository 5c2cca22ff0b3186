#include "storage/store_backend.h"

#include <string>

#include "storage/store_steps.h"

namespace forestmap::storage {

using Code = StorageError::Code;

MapRow RequireMap(StoreSession& session, const std::string& name) {
  std::optional<MapRow> map = session.FindMap(name);
  if (!map) throw StorageError(Code::kNotFound, "map '" + name + "' does not exist");
  return std::move(*map);
}

MapRow LockMap(StoreSession& session, const std::string& name) {
  MapRow map = RequireMap(session, name);
  // Read again once the lock is held: the map may have been changed, or deleted and created
  // again (another id, whose lock is then taken in turn), by a writer that held it.
  while (session.LockMap(map.id)) {
    const int64_t locked = map.id;
    map = RequireMap(session, name);
    if (map.id == locked) break;
  }
  return map;
}

VersionRecord RequireVersion(StoreSession& session, const MapRow& map, int64_t version) {
  if (std::optional<VersionRecord> found = session.FindVersion(map.id, version)) return *found;
  const int64_t oldest = session.OldestVersion(map.id).value_or(map.info.version);
  throw StorageError(Code::kNotFound, "map '" + map.info.name + "' has no version " +
                                          std::to_string(version) + "; versions " +
                                          std::to_string(oldest) + " to " +
                                          std::to_string(map.info.version) + " can be read");
}

void CommitWrite(StoreSession& session, StoreTransaction& transaction, const MapInfo& info) {
  if (const WriteRequest* request = CurrentWriteRequest()) {
    if (!request->id.empty()) {
      const int64_t now = internal::NowUnixMs();
      session.ExpireRequests(now - internal::kRequestLogRetentionMs);
      const StoredRequest answer{request->rpc,
                                 request->encode ? request->encode(info) : std::string(), now,
                                 request->fingerprint};
      if (!session.InsertRequest(request->id, answer)) ThrowAppliedConcurrently(*request);
    }
    CheckDeadlineBeforeCommit(*request);  // as close to COMMIT as possible
  }
  transaction.Commit();
}

void FreeRoom(StoreBackend& backend, const StoreBackend::Body& body) {
  try {
    backend.WithFreeingWriter(body);
  } catch (const StorageError& e) {
    const WriteRequest* request = CurrentWriteRequest();
    if (e.code() != Code::kFull || request == nullptr || request->id.empty()) throw;
    WriteRequest unrecorded = *request;
    unrecorded.id.clear();
    const WriteRequestScope scope(unrecorded);
    backend.WithFreeingWriter(body);
  }
}

}  // namespace forestmap::storage
