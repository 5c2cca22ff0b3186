#pragma once
// Exactly-once writes: a write with a client request id is applied at most once; a repeat of the
// id gets the first answer, stored in the database in the same transaction as the write
// (storage/write_request.h). Every write also carries its caller's deadline into the store, which
// refuses to commit once it has passed (DEADLINE_EXCEEDED, nothing written). Answers are bytes
// here; the transport encodes and decodes them (gRPC: server/grpc/replay.h).

#include <chrono>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

#include "server/app/errors.h"
#include "storage/map_store.h"
#include "storage/write_request.h"

namespace forestmap::server {

inline constexpr size_t kMaxRequestIdLength = 128;  // bytes

// A write as its client asked for it.
struct WriteCall {
  std::string request_id;  // the client's id; empty: none
  std::string rpc;         // the call, e.g. "UploadTrees": an id is never answered for another
  std::chrono::system_clock::time_point deadline = std::chrono::system_clock::time_point::max();
};

// What a write under exactly-once did: `outcome` when this call applied it, or else the stored
// answer of the earlier call with the same request id in `replayed` (`outcome` is then empty).
template <typename Outcome>
struct Written {
  Outcome outcome;
  std::optional<std::string> replayed;
};

// An id is empty (none) or 1..128 printable ASCII characters (0x21..0x7e): ValidationError
// naming `field` otherwise.
void ValidateRequestId(const std::string& id, const std::string& field = "request_id");

// The answer stored for `id` by an earlier write, or nullopt. An id answered for another call
// than `rpc` is a ValidationError.
std::optional<std::string> StoredAnswer(storage::MapStore& store, const std::string& id,
                                        std::string_view rpc);

// Runs `write` (which calls the store's write methods on this thread) under a WriteRequestScope
// of `call`; `encode(info)` gives the bytes of the answer stored with the write. Returns the
// stored answer of a repeated id without running `write` (and so for the loser of two
// concurrent calls with the same id), nullopt when `write` ran.
template <typename Write>
std::optional<std::string> WriteExactlyOnce(
    storage::MapStore& store, const WriteCall& call,
    std::function<std::string(const storage::MapInfo&)> encode, Write&& write) {
  ValidateRequestId(call.request_id);
  if (!call.request_id.empty()) {
    if (std::optional<std::string> stored = StoredAnswer(store, call.request_id, call.rpc)) {
      return stored;
    }
  }
  storage::WriteRequest request;
  request.id = call.request_id;
  request.rpc = call.rpc;
  request.encode = std::move(encode);
  request.deadline = call.deadline;
  const storage::WriteRequestScope scope(request);
  try {
    std::forward<Write>(write)();
  } catch (const storage::StorageError& e) {
    if (e.code() != storage::StorageError::Code::kConflict || call.request_id.empty()) throw;
    std::optional<std::string> stored = StoredAnswer(store, call.request_id, call.rpc);
    if (!stored) throw;
    return stored;
  }
  return std::nullopt;
}

}  // namespace forestmap::server
