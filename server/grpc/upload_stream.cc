// UploadTreesReactor (server/grpc/streams.h): uploads staged in the database as they arrive.

#include <memory>
#include <stdexcept>
#include <string>
#include <utility>

#include "server/app/map_crs.h"
#include "server/grpc/authorize.h"
#include "server/grpc/convert.h"
#include "server/grpc/replay.h"
#include "server/grpc/service.h"
#include "server/grpc/status.h"
#include "server/grpc/streams.h"

namespace forestmap::server {

UploadTreesReactor::UploadTreesReactor(const StreamDeps& deps, grpc::CallbackServerContext* context,
                                       grpc::ByteBuffer* response)
    : deps_(deps),
      authorizer_(deps.options.authorizer),
      context_(context),
      response_(response),
      validator_(deps.options.max_upload_trees) {
  std::string refusal;
  slot_ = deps_.limits.TryAcquire(context->peer(), "UploadTrees", refusal);
  if (!slot_) {
    const grpc::Status refused(grpc::StatusCode::RESOURCE_EXHAUSTED, refusal);
    LogStatus("UploadTrees", refused);
    End(refused);
    return;
  }
  StartRead(&buffer_);
}

void UploadTreesReactor::OnDone() {
  if (upload_) {
    // Not committed: removing its staged rows is a write, so it runs on a pool, not here.
    std::shared_ptr<storage::TreeUpload> upload(std::move(upload_));
    if (!deps_.admin_pool.TrySubmit([upload]() mutable { upload.reset(); })) upload.reset();
  }
  delete this;
}

void UploadTreesReactor::OnReadDone(bool ok) {
  if (!ok) {
    // The stream ended: either the client closed it (commit) or the call is gone.
    if (context_->IsCancelled()) {
      const grpc::Status cancelled(grpc::StatusCode::CANCELLED,
                                   "upload cancelled; nothing was written");
      LogStatus("UploadTrees", cancelled);
      End(cancelled);
      return;
    }
    const bool queued =
        deps_.work_pool.TrySubmit([this] { End(RunGuarded("UploadTrees", [this] { Commit(); })); });
    if (!queued) End(ServerBusy("UploadTrees"));
    return;
  }
  const bool first = validator_.messages() == 0;
  const grpc::Status status = RunGuarded("UploadTrees", [this, first] {
    Accept();  // decodes and checks the message; the first one names the map
  });
  if (!status.ok()) {
    End(status);  // the rest of the stream is dropped; nothing is committed
    return;
  }
  if (first) {
    // Fail early for an unknown (or, creating, an existing) map, before the client streams
    // millions of trees; a repeated request id is answered from the store.
    const bool queued = deps_.admin_pool.TrySubmit([this] {
      bool more = true;
      const grpc::Status begun = RunGuarded("UploadTrees", [this, &more] { more = Begin(); });
      if (!begun.ok()) {
        End(begun);
      } else if (more) {
        StartRead(&buffer_);
      } else {
        End(grpc::Status::OK);
      }
    });
    if (!queued) End(ServerBusy("UploadTrees"));
    return;
  }
  if (static_cast<int64_t>(chunk_.size()) >= deps_.options.upload_stage_trees) {
    ThenReadNext(deps_.work_pool, [this] { StageChunk(); });
    return;
  }
  StartRead(&buffer_);
}

void UploadTreesReactor::ThenReadNext(WorkerPool& pool, std::function<void()> body) {
  const bool queued = pool.TrySubmit([this, body = std::move(body)] {
    const grpc::Status status = RunGuarded("UploadTrees", body);
    if (status.ok()) {
      StartRead(&buffer_);
    } else {
      End(status);
    }
  });
  if (!queued) End(ServerBusy("UploadTrees"));
}

void UploadTreesReactor::Accept() {
  const grpc::Status decoded =
      grpc::SerializationTraits<v1::UploadTreesRequest>::Deserialize(&buffer_, &request_);
  buffer_.Clear();
  if (!decoded.ok()) {
    throw ServiceError(ErrorCode::kInvalidArgument,
                       "upload message " + std::to_string(validator_.messages()) + " (after " +
                           std::to_string(validator_.trees()) +
                           " trees) cannot be decoded as an UploadTreesRequest (a string that is "
                           "not UTF-8, or corrupt bytes); nothing was written");
  }
  const bool first = validator_.messages() == 0;
  const google::protobuf::RepeatedPtrField<v1::Tree> trees = validator_.Accept(request_);
  request_.Clear();
  if (first) {
    const v1::UploadTreesHeader& header = validator_.header();
    request_id_ = header.request_id();
    ValidateRequestId(request_id_);
    plan_.create_map = header.create_map();
    plan_.description = header.description();
    plan_.crs = header.crs();
  }
  for (const v1::Tree& tree : trees) chunk_.push_back(FromProto(tree));
}

bool UploadTreesReactor::Begin() {
  const std::string& name = validator_.header().name();
  Authorize(authorizer_, *context_, "UploadTrees", name);
  if (plan_.create_map) {
    Authorize(authorizer_, *context_, "CreateMap", name);  // creating needs CreateMap's role
    v1::CreateMapRequest create;
    create.set_name(name);
    create.set_description(plan_.description);
    create.set_crs(plan_.crs);
    Validate(create);
    plan_.crs = CanonicalCrs(plan_.crs);
  }
  v1::UploadTreesResponse replayed;
  if (!request_id_.empty() && ReplayRequest(deps_.store, request_id_, "UploadTrees", replayed)) {
    EncodeResponse(replayed);  // applied before: the first answer, nothing staged
    chunk_ = {};
    return false;
  }
  plan_.mode =
      validator_.header().replace() ? storage::WriteMode::kReplace : storage::WriteMode::kAppend;
  upload_ = deps_.store.BeginUpload(name, plan_);
  return true;
}

void UploadTreesReactor::StageChunk() {
  if (chunk_.empty()) return;
  upload_->Append(chunk_);
  chunk_.clear();
  chunk_.shrink_to_fit();  // an idle upload holds no trees
}

void UploadTreesReactor::Commit() {
  // The client may have given up while the commit waited in the work queue. (A cancel during
  // the final transaction cannot be honoured: it then commits whole.)
  if (context_->IsCancelled()) {
    throw ServiceError(ErrorCode::kCancelled, "upload cancelled; nothing was written");
  }
  validator_.Finish();
  StageChunk();
  const int64_t received = validator_.trees();
  const auto fill = [received](const storage::MapInfo& info, v1::UploadTreesResponse& answer) {
    *answer.mutable_map() = ToProto(info);
    answer.set_trees_received(received);
  };
  v1::UploadTreesResponse response;
  RunExactlyOnce(deps_.store, context_, request_id_, "UploadTrees", response,
                 Encoder<v1::UploadTreesResponse>(fill), [&] {
                   const storage::MapInfo info = upload_->Commit();
                   upload_.reset();  // committed: nothing to abort
                   fill(info, response);
                 });
  deps_.retention.AfterWrite(validator_.header().name());
  EncodeResponse(response);
}

void UploadTreesReactor::EncodeResponse(const v1::UploadTreesResponse& answer) {
  bool own_buffer = false;
  const grpc::Status encoded =
      grpc::SerializationTraits<v1::UploadTreesResponse>::Serialize(answer, response_, &own_buffer);
  if (!encoded.ok()) throw std::runtime_error("cannot encode the UploadTrees answer");
}

void UploadTreesReactor::End(const grpc::Status& status) {
  slot_.reset();  // before the client can learn the call ended and open the next one
  if (!upload_) {
    Finish(status);
    return;
  }
  // Not committed: its staged rows (and the map it was creating) go before the client learns
  // that the upload failed, so that a retry finds the name free. A write: on a pool.
  std::shared_ptr<storage::TreeUpload> upload(std::move(upload_));
  const bool queued = deps_.admin_pool.TrySubmit([this, upload, status]() mutable {
    upload.reset();
    Finish(status);
  });
  if (!queued) {
    upload.reset();
    Finish(status);
  }
}

}  // namespace forestmap::server
