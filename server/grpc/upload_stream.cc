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
#include "storage/token_store.h"

namespace forestmap::server {

UploadTreesReactor::UploadTreesReactor(const StreamDeps& deps, grpc::CallbackServerContext* context,
                                       grpc::ByteBuffer* response)
    : deps_(deps),
      authorizer_(deps.options.authorizer),
      context_(context),
      response_(response),
      watch_(deps.idle.Add(*context, "UploadTrees")),
      validator_(deps.options.max_upload_trees) {
  // The token check reads the token store: on a pool, not on gRPC's thread.
  if (!deps_.admin_pool.TrySubmit([this] { Open(); })) End(ServerBusy("UploadTrees"));
}

void UploadTreesReactor::Open() {
  const grpc::Status opened = RunGuarded("UploadTrees", [this] {
    slot_ = OpenStream(authorizer_, deps_.limits, *context_, "UploadTrees", "");
  });
  if (opened.ok()) {
    Read();
  } else {
    End(opened);
  }
}

void UploadTreesReactor::Read() {
  watch_->Waiting();
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
  watch_->Working();
  if (!ok) {
    // The stream ended: either the client closed it (commit) or the call is gone.
    if (context_->IsCancelled()) {
      const grpc::Status cancelled(grpc::StatusCode::CANCELLED,
                                   "upload cancelled; nothing was written");
      LogStatus("UploadTrees", cancelled);
      End(cancelled);
      return;
    }
    const bool queued = deps_.write_pool.TrySubmit(
        [this] { End(RunGuarded("UploadTrees", [this] { Commit(); })); });
    if (!queued) End(ServerBusy("UploadTrees"));
    return;
  }
  const bool first = validator_.messages() == 0;
  const grpc::Status status = RunGuarded("UploadTrees", [this] {
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
      const grpc::Status begun = RunGuarded("UploadTrees", [this] { Begin(); });
      if (begun.ok()) {
        Read();
      } else {
        End(begun);
      }
    });
    if (!queued) End(ServerBusy("UploadTrees"));
    return;
  }
  if (static_cast<int64_t>(chunk_.size()) >= deps_.options.upload_stage_trees) {
    ThenReadNext(deps_.write_pool, [this] { StageChunk(); });
    return;
  }
  Read();
}

void UploadTreesReactor::ThenReadNext(WorkerPool& pool, std::function<void()> body) {
  const bool queued = pool.TrySubmit([this, body = std::move(body)] {
    const grpc::Status status = RunGuarded("UploadTrees", body);
    if (status.ok()) {
      Read();
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
  digest_ = storage::Sha256Hex(digest_ + ContentDigest(request_));  // the request's content
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
    if (header.has_boundary()) plan_.boundary = FromProto(header.boundary());
    plan_.attribute_columns.assign(header.attribute_columns().begin(),
                                   header.attribute_columns().end());
  }
  if (replaying_) return;  // read to know the request, not to write it again
  for (const v1::Tree& tree : trees) chunk_.push_back(FromProto(tree));
}

void UploadTreesReactor::Begin() {
  const std::string& name = validator_.header().name();
  caller_ = Authorize(authorizer_, *context_, "UploadTrees", name);
  if (plan_.create_map) {
    Authorize(authorizer_, *context_, "CreateMap", name);  // creating needs CreateMap's role
    v1::CreateMapRequest create;
    create.set_name(name);
    create.set_description(plan_.description);
    create.set_crs(plan_.crs);
    Validate(create);
    plan_.crs = CanonicalCrs(plan_.crs);
  }
  if (!request_id_.empty() && FindStoredRequest(deps_.store, request_id_, "UploadTrees")) {
    // Applied before, perhaps: the id is bound to the whole request, so the rest is read (and
    // checked) without staging it, and answered from the store only if it is the same request.
    replaying_ = true;
    chunk_ = {};
    return;
  }
  plan_.mode =
      validator_.header().replace() ? storage::WriteMode::kReplace : storage::WriteMode::kAppend;
  upload_ = deps_.store.BeginUpload(name, plan_);
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
  const WriteCall call = WriteCallOf(context_, caller_, "UploadTrees", validator_.header().name(),
                                     request_id_, digest_);
  if (replaying_) {
    v1::UploadTreesResponse replayed;
    if (!ReplayRequest(deps_.store, call, replayed)) {
      throw ServiceError(ErrorCode::kAborted, "the stored answer of request id '" + request_id_ +
                                                  "' expired during the upload; nothing was "
                                                  "written: retry with a new id");
    }
    EncodeResponse(replayed);  // applied before: the first answer, nothing staged
    return;
  }
  StageChunk();
  const int64_t received = validator_.trees();
  const auto fill = [received](const storage::MapInfo& info, v1::UploadTreesResponse& answer) {
    *answer.mutable_map() = ToProto(info);
    answer.set_trees_received(received);
  };
  v1::UploadTreesResponse response;
  RunExactlyOnce(deps_.store, call, response, Encoder<v1::UploadTreesResponse>(fill), [&] {
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
