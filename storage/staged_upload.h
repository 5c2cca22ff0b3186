#pragma once
// An upload staged in the database (storage/staged_writes.h), written once: the checks of each
// chunk, ids, running counts, and the commit's rules (when a version is made, what it counts,
// when the answer of an exactly-once write is stored). A backend derives from StagedUpload and
// says only where the chunks go and how they become the map's rows. Not a public API.

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "storage/staged_writes.h"
#include "storage/store_backend.h"
#include "storage/upload_chunks.h"

namespace forestmap::storage {

class StagedUpload : public TreeUpload {
 public:
  void Append(const std::vector<TreeRecord>& trees) final;
  MapInfo Commit() final;
  int64_t staged() const final { return chunks_.staged(); }

 protected:
  // kInvalidArgument for an invalid plan.boundary (storage/boundary_json.h).
  StagedUpload(std::string name, UploadPlan plan);

  // Ends an upload that is not over (committed or aborted): Abort(). Also for the backend's
  // destructor.
  void Discard() noexcept;

  const std::string& name() const { return name_; }
  const UploadPlan& plan() const { return plan_; }
  internal::UploadChunks& chunks() { return chunks_; }

  // ---- What the backend does ----

  // Stages one chunk of checked trees (ids from chunks().Assign) in the database.
  virtual void Stage(const std::vector<TreeRecord>& trees) = 0;
  // Runs `body` on the upload's connection for its commit.
  virtual void WithSession(const std::function<void(StoreSession&)>& body) = 0;
  // In the commit's write transaction: the map the upload writes, locked; created (or revealed)
  // when the plan says so. kNotFound when it was deleted during the upload.
  virtual MapRow Target(StoreSession& session) = 0;
  // In it too: the staged rows become current rows of the map from `version` on.
  // kInvalidArgument naming the tree for an appended id the map has.
  virtual void MakeCurrent(StoreSession& session, const MapRow& map, int64_t version) = 0;
  // In it, last: what the upload kept of itself in the database.
  virtual void Forget(StoreSession& /*session*/) {}
  // After a failed Append or Commit, or when destroyed unfinished: the staged rows go.
  virtual void Abort() noexcept = 0;
  // After the commit, outside its transaction.
  virtual void Finished() noexcept {}

 private:
  // In the commit: the encoded plan.boundary when it differs from the map's current one.
  std::optional<std::string> NewBoundary(StoreSession& session, const MapRow& map);
  // In the commit: the encoded order of the attribute columns from the new version on when the
  // upload changes it (storage/attribute_json.h), else "".
  std::string NewColumns(StoreSession& session, int64_t map_id, int64_t old_version, bool replace);

  std::string name_;
  UploadPlan plan_;
  internal::UploadChunks chunks_;
  bool done_ = false;  // committed or aborted
};

}  // namespace forestmap::storage
