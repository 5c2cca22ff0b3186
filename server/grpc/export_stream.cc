// ExportTreesReactor (server/grpc/streams.h): exports read page by page, with flow control.

#include <string>
#include <utility>

#include "server/grpc/authorize.h"
#include "server/grpc/convert.h"
#include "server/grpc/service.h"
#include "server/grpc/status.h"
#include "server/grpc/streams.h"

namespace forestmap::server {

ExportTreesReactor::ExportTreesReactor(const StreamDeps& deps, grpc::CallbackServerContext* context,
                                       const v1::ExportTreesRequest* request)
    : deps_(deps), context_(context), request_(request) {
  std::string refusal;
  slot_ = deps_.limits.TryAcquire(context->peer(), "ExportTrees", refusal);
  if (!slot_) {
    const grpc::Status refused(grpc::StatusCode::RESOURCE_EXHAUSTED, refusal);
    LogStatus("ExportTrees", refused);
    End(refused);
    return;
  }
  ReadThenWrite(/*start=*/true);
}

void ExportTreesReactor::Start() {
  const v1::ExportTreesRequest& request = *request_;
  Authorize(deps_.options.authorizer, *context_, "ExportTrees", request.name());
  Validate(request);
  storage::MapInfo info = deps_.store.GetMap(request.name());
  if (request.version() != 0) info.version = request.version();
  version_ = info.version;
  std::optional<storage::Extent> box;
  if (request.has_box()) box = FromProto(request.box());
  pages_.emplace(deps_.store, info, deps_.options.export_chunk_trees, box);
}

void ExportTreesReactor::LoadPage() {
  page_ = pages_->Next();
  next_ = 0;
}

void ExportTreesReactor::ReadThenWrite(bool start) {
  const bool queued = deps_.work_pool.TrySubmit([this, start] {
    const grpc::Status status = RunGuarded("ExportTrees", [this, start] {
      if (start) Start();
      LoadPage();
    });
    if (status.ok()) {
      WriteNext();
    } else {
      End(status);
    }
  });
  if (!queued) End(ServerBusy("ExportTrees"));
}

void ExportTreesReactor::WriteNext() {
  if (next_ >= page_.size()) {
    if (!pages_->done()) {
      ReadThenWrite(/*start=*/false);  // the client took the last message: read on
      return;
    }
    if (wrote_any_) {
      page_ = {};
      End(grpc::Status::OK);
      return;
    }
  }
  response_.Clear();
  response_.set_map_version(version_);
  const int64_t chunk_trees = deps_.options.export_chunk_trees;
  const int64_t chunk_bytes = deps_.options.export_chunk_bytes;
  int64_t bytes = 0;
  while (next_ < page_.size() && response_.trees_size() < chunk_trees && bytes < chunk_bytes) {
    v1::Tree* tree = response_.add_trees();
    *tree = ToProto(page_[next_++]);
    bytes += static_cast<int64_t>(tree->ByteSizeLong());
  }
  wrote_any_ = true;
  StartWrite(&response_);
}

void ExportTreesReactor::OnWriteDone(bool ok) {
  if (!ok) {
    const grpc::Status cancelled(grpc::StatusCode::CANCELLED, "the client stopped reading");
    LogStatus("ExportTrees", cancelled);
    End(cancelled);
    return;
  }
  WriteNext();
}

void ExportTreesReactor::End(const grpc::Status& status) {
  slot_.reset();  // before the client can learn the call ended and open the next one
  Finish(status);
}

}  // namespace forestmap::server
