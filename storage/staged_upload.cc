#include "storage/staged_upload.h"

namespace forestmap::storage {

using Code = StorageError::Code;

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
      const bool changes = chunks_.staged() > 0 || (replace && map.info.tree_count > 0);
      if (changes) {
        const int64_t version = map.info.version + 1;
        // A created map has no old rows: its current rows are the upload's.
        const int64_t closed =
            replace && !plan_.create_map ? session.CloseAllRows(map.id, version) : 0;
        MakeCurrent(session, map, version);
        const VersionRecord record = chunks_.Apply(map.info, closed);
        session.UpdateMap(map);
        session.InsertVersion(map.id, record);
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

void StagedUpload::Discard() noexcept {
  if (done_) return;
  done_ = true;
  Abort();
}

}  // namespace forestmap::storage
