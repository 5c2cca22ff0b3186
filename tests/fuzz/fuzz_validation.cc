// libFuzzer target for the server's request validation (server/grpc/validation.h): the first byte
// picks a request message, the rest is parsed as that message (bytes that do not parse are what
// the server answers INVALID_ARGUMENT before validating), then validated. Validation must answer
// with ServiceError; any other exception or a sanitizer report is a crash. A request that passes
// must keep every tree coordinate within the documented local-frame bounds (a tree at 1e308
// must never reach the index).
#include <google/protobuf/stubs/logging.h>

#include <cmath>
#include <cstdint>
#include <string>

#include "server/grpc/upload_validator.h"
#include "server/grpc/validation.h"

namespace fs = forestmap::server;
namespace v1 = forestmap::v1;

namespace {

void Check(bool ok) {
  if (!ok) __builtin_trap();
}

void CheckPosition(double x, double y, double z) {
  Check(std::fabs(x) < fs::kMaxHorizontalCoordinate &&
        std::fabs(y) < fs::kMaxHorizontalCoordinate && std::fabs(z) < fs::kMaxVerticalCoordinate);
}

template <typename Trees>
void CheckDetected(const Trees& trees) {
  for (const v1::DetectedTree& tree : trees) {
    CheckPosition(tree.position().x(), tree.position().y(), tree.position().z());
  }
}

// The message as the first of a stream, then again as the second (a second header, or the same
// trees again in the 0.1.0 layout), in either layout.
void Upload(const v1::UploadTreesRequest& message) {
  fs::UploadValidator validator(/*max_trees=*/100'000);
  v1::UploadTreesRequest first = message;
  for (const v1::Tree& tree : validator.Accept(first)) CheckPosition(tree.x(), tree.y(), tree.z());
  v1::UploadTreesRequest next = message;
  for (const v1::Tree& tree : validator.Accept(next)) CheckPosition(tree.x(), tree.y(), tree.z());
  validator.Finish();
}

// The message as the first of a Track stream, and as a later one.
void Track(const v1::TrackRequest& message) {
  for (const char* session_map : {"", "forest"}) {
    v1::TrackRequest copy = message;
    const fs::TrackMessage read = fs::ReadTrackMessage(copy, session_map, 1'000);
    if (read.frame) CheckDetected(read.frame->trees());
  }
}

template <typename Message, typename Validate>
void Run(const uint8_t* data, size_t size, Validate validate) {
  Message message;
  if (!message.ParseFromArray(data, static_cast<int>(size))) return;
  try {
    validate(message);
  } catch (const fs::ServiceError&) {
  }
}

}  // namespace

// Protobuf logs every string field with invalid UTF-8 it refuses to parse: not news here.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
  google::protobuf::SetLogHandler(nullptr);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const uint8_t kind = data[0] % 11;
  ++data;
  --size;
  const fs::ObserveLimits observe_limits{/*max_frames=*/20, /*max_frame_trees=*/200,
                                         /*max_request_trees=*/1'000};
  switch (kind) {
    case 0:
      return Run<v1::CreateMapRequest>(data, size, [](const auto& m) { fs::Validate(m); }), 0;
    case 1:
      return Run<v1::GetMapRequest>(data, size, [](const auto& m) { fs::Validate(m); }), 0;
    case 2:
      return Run<v1::DeleteMapRequest>(data, size, [](const auto& m) { fs::Validate(m); }), 0;
    case 3:
      return Run<v1::ExportTreesRequest>(data, size, [](const auto& m) { fs::Validate(m); }), 0;
    case 4:
      return Run<v1::RelocalizeRequest>(data, size,
                                        [](const auto& m) {
                                          fs::Validate(m, /*max_query_trees=*/1'000);
                                          CheckDetected(m.trees());
                                        }),
             0;
    case 5:
      return Run<v1::TrackRequest>(data, size, Track), 0;
    case 6:
      return Run<v1::ObserveRequest>(data, size,
                                     [&](const auto& m) {
                                       fs::Validate(m, observe_limits);
                                       for (const v1::ObservationFrame& frame : m.frames())
                                         CheckDetected(frame.trees());
                                     }),
             0;
    case 7:
      return Run<v1::ListVersionsRequest>(data, size, [](const auto& m) { fs::Validate(m); }), 0;
    case 8:
      return Run<v1::RestoreVersionRequest>(data, size, [](const auto& m) { fs::Validate(m); }), 0;
    case 9:
      return Run<v1::RemoveSourceRequest>(data, size, [](const auto& m) { fs::Validate(m); }), 0;
    default:
      return Run<v1::UploadTreesRequest>(data, size, Upload), 0;
  }
}
