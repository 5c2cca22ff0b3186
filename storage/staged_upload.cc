#include "storage/staged_upload.h"

#include "storage/attribute_json.h"
#include "storage/boundary_json.h"

namespace forestmap::storage {

using Code = StorageError::Code;

StagedUpload::StagedUpload(std::string name, UploadPlan plan)
    : name_(std::move(name)), plan_(std::move(plan)), chunks_(name_, plan_.mode) {
  if (plan_.boundary) internal::CheckBoundary(name_, *plan_.boundary);
}

void StagedUpload::Append(const std::vector<TreeRecord>& trees) {
  if (done_) throw StorageError(Code::kInternal, "upload to '" + name_ + "' already finished");
  if (trees.empty()) return;
  try {
    chunks_.Check(trees);
    Stage(trees);
  } catch (...) {
    Discard();  // a failed upload is over: its staged rows go now
    throw;
  }
  chunks_.Staged(trees);
}

MapInfo StagedUpload::Commit() {
  if (done_) throw StorageError(Code::kInternal, "upload to '" + name_ + "' already finished");
  MapInfo result;
  try {
    WithSession([&](StoreSession& session) {
      StoreTransaction transaction(session, TransactionKind::kWrite);
      MapRow map = Target(session);
      const bool replace = plan_.mode == WriteMode::kReplace;
      const std::optional<std::string> boundary = NewBoundary(session, map);
      const bool changes =
          chunks_.staged() > 0 || (replace && map.info.tree_count > 0) || boundary.has_value();
      if (changes) {
        const int64_t version = map.info.version + 1;
        // A created map has no old rows: its current rows are the upload's.
        const int64_t closed =
            replace && !plan_.create_map ? session.CloseAllRows(map.id, version) : 0;
        MakeCurrent(session, map, version);
        const VersionRecord record = chunks_.Apply(map.info, closed);
        session.UpdateMap(map);
        session.InsertVersion(map.id, record);
        if (boundary) {
          session.InsertBoundary(map.id, map.info.version, *boundary);
          map.info.has_boundary = !boundary->empty();
        }
        const std::string columns = NewColumns(session, map.id, version - 1, replace);
        if (!columns.empty()) session.InsertColumns(map.id, version, columns);
      }
      Forget(session);
      if (changes || plan_.create_map) {
        CommitWrite(session, transaction, map.info);
      } else {
        transaction.Commit();  // nothing changed: no version, no answer stored
      }
      result = map.info;
    });
  } catch (...) {
    Discard();
    throw;
  }
  done_ = true;
  Finished();
  return result;
}

std::optional<std::string> StagedUpload::NewBoundary(StoreSession& session, const MapRow& map) {
  if (!plan_.boundary) return std::nullopt;
  std::string encoded = internal::EncodeBoundary(*plan_.boundary);
  if (encoded == session.BoundaryAt(map.id, map.info.version)) return std::nullopt;
  return encoded;
}

std::string StagedUpload::NewColumns(StoreSession& session, int64_t map_id, int64_t old_version,
                                     bool replace) {
  if (plan_.attribute_columns.empty()) return {};
  const std::string stored = session.ColumnsAt(map_id, old_version);
  std::string merged = internal::EncodeColumnOrder(internal::MergeColumnOrder(
      internal::DecodeColumnOrder(name_, stored), plan_.attribute_columns, replace));
  return merged == stored ? std::string() : merged;
}

void StagedUpload::Discard() noexcept {
  if (done_) return;
  done_ = true;
  Abort();
}

}  // namespace forestmap::storage
