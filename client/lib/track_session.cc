// ForestMapClient::Track and its TrackSession: one Track stream for a whole flight.

#include <optional>
#include <stdexcept>
#include <utility>

#include "client/lib/forestmap_client.h"
#include "client/lib/proto_convert.h"

namespace forestmap::client {

TrackSession ForestMapClient::Track(const std::string& name) {
  MapSelection one;
  one.name = name;
  return Track(one);
}

TrackSession ForestMapClient::Track(const MapSelection& maps) {
  v1::TrackHeader header;
  header.set_name(maps.name);
  if (std::optional<v1::MapSet> set = MapSetOf(maps)) *header.mutable_maps() = std::move(*set);
  auto context = NewContext(/*timeout=*/0);  // a session lasts as long as the flight
  auto stream = stub_->Track(context.get());
  return TrackSession(*this, std::move(header), std::move(context), std::move(stream));
}

TrackSession::TrackSession(
    ForestMapClient& client, v1::TrackHeader header, std::unique_ptr<grpc::ClientContext> context,
    std::unique_ptr<grpc::ClientReaderWriter<v1::TrackRequest, v1::TrackResponse>> stream)
    : client_(&client),
      header_(std::move(header)),
      context_(std::move(context)),
      stream_(std::move(stream)) {}

TrackSession::~TrackSession() {
  if (!stream_) return;
  context_->TryCancel();
  stream_->Finish();
}

v1::TrackResponse TrackSession::Step(const TrackFrame& frame) {
  if (!stream_) throw std::logic_error("TrackSession::Step after Finish");
  v1::TrackRequest header;  // the first message names the map (or maps), and gets no answer
  *header.mutable_header() = header_;
  v1::TrackRequest request;
  v1::TrackFrame& out = *request.mutable_frame();
  out.set_frame_id(frame.frame_id);
  out.mutable_trees()->Reserve(static_cast<int>(frame.trees.size()));
  for (const algorithms::DetectedTree& tree : frame.trees) *out.add_trees() = ToProto(tree);
  if (frame.gravity) *out.mutable_gravity() = ToProto(*frame.gravity);
  if (frame.odometry) *out.mutable_odometry() = ToProto(*frame.odometry);
  v1::TrackResponse response;
  if ((first_ && !stream_->Write(header)) || !stream_->Write(request) ||
      !stream_->Read(&response)) {
    // The server ended the session: its status says why.
    const grpc::Status status = stream_->Finish();
    stream_.reset();
    client_->Check(status.ok() ? grpc::Status(grpc::StatusCode::INTERNAL,
                                              "the server closed the session without an answer")
                               : status,
                   "Track");
  }
  first_ = false;
  client_->connected_ = true;
  return response;
}

void TrackSession::Finish() {
  if (!stream_) return;
  stream_->WritesDone();
  const grpc::Status status = stream_->Finish();
  stream_.reset();
  client_->Check(status, "Track");
}

}  // namespace forestmap::client
