#pragma once
// Limits on the streaming RPCs, for bounded memory and so that no caller can hold them all:
//   - concurrent UploadTrees and ExportTrees streams: each open stream holds up to one staging
//     chunk or one export page in memory, so their number bounds the server's memory. A stream
//     is authorized as it opens (its token is in the call's metadata), so a call without a valid
//     token, or without the role the RPC needs, never takes a place. A caller is its token, or
//     its connection (gRPC peer address, "ipv4:10.0.0.7:53122") on a server without tokens; one
//     caller holds at most max_streams_per_client places and never more than half of them all.
//   - idle streams (IdleStreams): a stream waiting longer than idle_timeout for its client (the
//     next message of an upload or a Track session, or an export's client taking the last one)
//     is cancelled, which frees its place. Upload, export and Track streams are watched. The
//     watch also checks each stream's token again every token_recheck (5 s): a stream whose token
//     was revoked (or the server closed since) is cancelled too.

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <unordered_map>

namespace forestmap::server {

class Authorizer;

struct StreamLimitOptions {
  int max_streams = 64;            // open upload + export streams in all, count
  int max_streams_per_client = 8;  // ... of one caller, count (at most half of max_streams, up)
  // A stream waiting this long for its client is cancelled (ms, >= 1).
  std::chrono::milliseconds idle_timeout{30'000};
  // An open stream's token is checked again this often (ms, >= 1): revoked, it is cancelled.
  std::chrono::milliseconds token_recheck{5'000};
  void Check() const;     // throws std::invalid_argument
  int PerCaller() const;  // the places one caller may hold
};

class StreamLimits {
 public:
  // Held by an open stream; releases its place when destroyed.
  class Slot {
   public:
    Slot(StreamLimits& limits, std::string caller) : limits_(limits), caller_(std::move(caller)) {}
    ~Slot() { limits_.Release(caller_); }
    Slot(const Slot&) = delete;
    Slot& operator=(const Slot&) = delete;

   private:
    StreamLimits& limits_;
    std::string caller_;
  };

  explicit StreamLimits(const StreamLimitOptions& options) : options_(options) {}

  // A place for a new stream of `rpc` from `caller` (a token or a connection, named in
  // messages), or null with `refusal` set to a message for RESOURCE_EXHAUSTED naming the limit.
  // Thread-safe.
  std::unique_ptr<Slot> TryAcquire(const std::string& caller, const char* rpc,
                                   std::string& refusal);
  int open() const;  // streams open now

 private:
  void Release(const std::string& caller);

  StreamLimitOptions options_;
  mutable std::mutex mutex_;
  int open_ = 0;
  std::map<std::string, int> per_caller_;
};

// Authorizes a stream of `rpc` as it opens (the role the RPC needs on `map`; an empty `map`: on
// some map, the map being checked on the stream's first message), then takes its place. Throws
// ServiceError: UNAUTHENTICATED, PERMISSION_DENIED, RESOURCE_EXHAUSTED (limits).
std::unique_ptr<StreamLimits::Slot> OpenStream(const Authorizer* authorizer, StreamLimits& limits,
                                               const grpc::ServerContextBase& context,
                                               const char* rpc, std::string_view map);

// Cancels streams that wait for their client longer than a timeout, and streams whose caller is
// no longer authenticated (a revoked token). A watching thread checks every quarter of the
// shorter of the two periods (at most every second). Thread-safe.
class IdleStreams {
 public:
  // `authorizer` null: no token checks; else it must outlive this.
  IdleStreams(const StreamLimitOptions& options, const Authorizer* authorizer);
  ~IdleStreams();  // stops the watching thread; every Watch must be gone before
  IdleStreams(const IdleStreams&) = delete;
  IdleStreams& operator=(const IdleStreams&) = delete;

  struct State;
  // Held by a stream (reactor) for its life; the stream says when it waits for its client.
  class Watch {
   public:
    Watch(IdleStreams& owner, std::shared_ptr<State> state)
        : owner_(owner), state_(std::move(state)) {}
    ~Watch();  // may run inside the cancellation it watched for
    Watch(const Watch&) = delete;
    Watch& operator=(const Watch&) = delete;
    void Waiting();  // from now on the stream waits for its client (a read or write is pending)
    void Working();  // the server works on the stream: not idle

   private:
    IdleStreams& owner_;
    std::shared_ptr<State> state_;
  };

  // Watches the stream of `rpc` on `context`, which must outlive the Watch. It starts working.
  std::unique_ptr<Watch> Add(grpc::ServerContextBase& context, const char* rpc);

 private:
  void Run();
  void CancelIdle();
  // A stream whose call's token no longer authenticates ("" when it does).
  std::string Unauthenticated(const grpc::ServerContextBase& context) const;

  const std::chrono::milliseconds timeout_;
  const std::chrono::milliseconds token_recheck_;
  const Authorizer* authorizer_;
  int64_t last_token_check_ns_ = 0;  // steady clock; only the watching thread uses it
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_ = false;
  std::unordered_map<const State*, std::shared_ptr<State>> streams_;
  std::thread thread_;  // last: started when the rest is ready
};

}  // namespace forestmap::server
