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
    : deps_(deps),
      context_(context),
      request_(request),
      watch_(deps.idle.Add(*context, "ExportTrees")) {
  ReadThenWrite(/*start=*/true);
}

void ExportTreesReactor::Start() {
  const v1::ExportTreesRequest& request = *request_;
  // The map is known as the stream opens: the whole check before it takes a place.
  slot_ =
      OpenStream(deps_.options.authorizer, deps_.limits, *context_, "ExportTrees", request.name());
  Validate(request);
  storage::MapInfo info = deps_.store.GetMap(request.name());
  if (request.version() != 0) info.version = request.version();
  version_ = info.version;
  std::optional<storage::Extent> box;
  if (request.has_box()) box = FromProto(request.box());
  pages_.emplace(deps_.store, info, deps_.options.export_chunk_trees, box);
  boundary_ = deps_.store.ReadBoundary(request.name(), version_);
  attribute_columns_ = deps_.store.ReadAttributeColumns(request.name(), version_);
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
  if (!wrote_any_ && !boundary_.empty()) {
    *response_.mutable_boundary() = ToProto(boundary_);
    boundary_ = {};
  }
  if (!wrote_any_) {
    for (const std::string& name : attribute_columns_) response_.add_attribute_columns(name);
  }
  const int64_t chunk_trees = deps_.options.export_chunk_trees;
  const int64_t chunk_bytes = deps_.options.export_chunk_bytes;
  int64_t bytes = static_cast<int64_t>(response_.ByteSizeLong());  // the boundary counts too
  while (next_ < page_.size() && response_.trees_size() < chunk_trees && bytes < chunk_bytes) {
    v1::Tree* tree = response_.add_trees();
    *tree = ToProto(page_[next_++]);
    bytes += static_cast<int64_t>(tree->ByteSizeLong());
  }
  wrote_any_ = true;
  watch_->Waiting();  // until the client takes the message
  StartWrite(&response_);
}

void ExportTreesReactor::OnWriteDone(bool ok) {
  watch_->Working();
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
