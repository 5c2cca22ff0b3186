#pragma once
// Limits on concurrent UploadTrees and ExportTrees streams, for bounded memory: each open
// stream holds up to one staging chunk or one export page in memory, so their number bounds the
// server's memory. A client is a connection (gRPC peer address, "ipv4:10.0.0.7:53122").

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>

namespace forestmap::server {

struct StreamLimitOptions {
  int max_streams = 64;            // open upload + export streams in all, count
  int max_streams_per_client = 8;  // open upload + export streams of one connection, count
  void Check() const;              // throws std::invalid_argument
};

class StreamLimits {
 public:
  // Held by an open stream; releases its place when destroyed.
  class Slot {
   public:
    Slot(StreamLimits& limits, std::string peer) : limits_(limits), peer_(std::move(peer)) {}
    ~Slot() { limits_.Release(peer_); }
    Slot(const Slot&) = delete;
    Slot& operator=(const Slot&) = delete;

   private:
    StreamLimits& limits_;
    std::string peer_;
  };

  explicit StreamLimits(const StreamLimitOptions& options) : options_(options) {}

  // A place for a new stream of `rpc` from `peer`, or null with `refusal` set to a message for
  // RESOURCE_EXHAUSTED naming the limit. Thread-safe.
  std::unique_ptr<Slot> TryAcquire(const std::string& peer, const char* rpc, std::string& refusal);
  int open() const;  // streams open now

 private:
  void Release(const std::string& peer);

  StreamLimitOptions options_;
  mutable std::mutex mutex_;
  int open_ = 0;
  std::map<std::string, int> per_peer_;
};

}  // namespace forestmap::server
