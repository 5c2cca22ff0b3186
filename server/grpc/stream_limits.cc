#include "server/grpc/stream_limits.h"

#include <algorithm>
#include <atomic>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "server/app/errors.h"
#include "server/grpc/authorize.h"
#include "server/grpc/status.h"

namespace forestmap::server {

void StreamLimitOptions::Check() const {
  if (max_streams < 1) throw std::invalid_argument("StreamLimitOptions.max_streams must be >= 1");
  if (max_streams_per_client < 1) {
    throw std::invalid_argument("StreamLimitOptions.max_streams_per_client must be >= 1");
  }
  if (idle_timeout.count() < 1) {
    throw std::invalid_argument("StreamLimitOptions.idle_timeout must be >= 1 ms");
  }
  if (token_recheck.count() < 1) {
    throw std::invalid_argument("StreamLimitOptions.token_recheck must be >= 1 ms");
  }
}

int StreamLimitOptions::PerCaller() const {
  return std::min(max_streams_per_client, (max_streams + 1) / 2);
}

std::unique_ptr<StreamLimits::Slot> StreamLimits::TryAcquire(const std::string& caller,
                                                             const char* rpc,
                                                             std::string& refusal) {
  std::lock_guard<std::mutex> lock(mutex_);
  int& mine = per_caller_[caller];
  if (mine >= options_.PerCaller()) {
    refusal = std::string(rpc) + ": this client (" + caller + ") already has " +
              std::to_string(mine) + " upload/export streams open, the limit per client " +
              std::to_string(options_.PerCaller()) + " (forestmapd --max-streams-per-client " +
              std::to_string(options_.max_streams_per_client) +
              ", at most half of --max-streams); finish one and retry";
  } else if (open_ >= options_.max_streams) {
    refusal = std::string(rpc) + ": the server has " + std::to_string(open_) +
              " upload/export streams open, its limit (forestmapd --max-streams " +
              std::to_string(options_.max_streams) + "); retry later";
  } else {
    ++mine;
    ++open_;
    return std::make_unique<Slot>(*this, caller);
  }
  if (mine == 0) per_caller_.erase(caller);
  return nullptr;
}

void StreamLimits::Release(const std::string& caller) {
  std::lock_guard<std::mutex> lock(mutex_);
  --open_;
  const auto it = per_caller_.find(caller);
  if (it != per_caller_.end() && --it->second <= 0) per_caller_.erase(it);
}

int StreamLimits::open() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return open_;
}

std::unique_ptr<StreamLimits::Slot> OpenStream(const Authorizer* authorizer, StreamLimits& limits,
                                               const grpc::ServerContextBase& context,
                                               const char* rpc, std::string_view map) {
  const Caller caller = Authorize(authorizer, context, rpc, map);
  const std::string key =
      caller.token ? "token " + std::to_string(caller.token->id) : "connection " + context.peer();
  std::string refusal;
  std::unique_ptr<StreamLimits::Slot> slot = limits.TryAcquire(key, rpc, refusal);
  if (!slot) throw ServiceError(ErrorCode::kResourceExhausted, refusal);
  return slot;
}

// ---- IdleStreams ----

struct IdleStreams::State {
  grpc::ServerContextBase* context;
  const char* rpc;
  std::atomic<int64_t> waiting_since_ns{0};  // steady clock; 0: working
  bool cancelled = false;                    // under IdleStreams::mutex_
  // Held while the stream is cancelled, and by the Watch when it ends: the context lives until
  // then. Recursive: gRPC may end the stream (and so the Watch) inside TryCancel, on this thread.
  std::recursive_mutex cancel_mutex;
  bool alive = true;  // under cancel_mutex
};

namespace {

int64_t NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

IdleStreams::IdleStreams(const StreamLimitOptions& options, const Authorizer* authorizer)
    : timeout_(options.idle_timeout),
      token_recheck_(options.token_recheck),
      authorizer_(authorizer),
      thread_([this] { Run(); }) {}

IdleStreams::~IdleStreams() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

std::unique_ptr<IdleStreams::Watch> IdleStreams::Add(grpc::ServerContextBase& context,
                                                     const char* rpc) {
  auto state = std::make_shared<State>();
  state->context = &context;
  state->rpc = rpc;
  std::lock_guard<std::mutex> lock(mutex_);
  streams_.emplace(state.get(), state);
  return std::make_unique<Watch>(*this, std::move(state));
}

IdleStreams::Watch::~Watch() {
  {
    std::lock_guard<std::recursive_mutex> lock(state_->cancel_mutex);
    state_->alive = false;
  }
  std::lock_guard<std::mutex> lock(owner_.mutex_);
  owner_.streams_.erase(state_.get());
}

void IdleStreams::Watch::Waiting() { state_->waiting_since_ns = NowNs(); }

void IdleStreams::Watch::Working() { state_->waiting_since_ns = 0; }

void IdleStreams::Run() {
  const auto period =
      std::clamp(timeout_ / 4, std::chrono::milliseconds(5), std::chrono::milliseconds(1000));
  std::unique_lock<std::mutex> lock(mutex_);
  while (!wake_.wait_for(lock, period, [this] { return stop_; })) {
    lock.unlock();
    CancelIdle();
    lock.lock();
  }
}

std::string IdleStreams::Unauthenticated(const grpc::ServerContextBase& context) const {
  if (authorizer_ == nullptr) return "";
  std::optional<std::string_view> authorization;
  const auto& metadata = context.client_metadata();
  const auto it = metadata.find("authorization");
  if (it != metadata.end()) authorization.emplace(it->second.data(), it->second.size());
  try {
    authorizer_->Authenticate(authorization);
    return "";
  } catch (const ServiceError& e) {
    return e.code() == ErrorCode::kUnauthenticated ? e.what() : "";
  } catch (...) {
    return "";  // a fault of the token store: the stream's own calls will report it
  }
}

void IdleStreams::CancelIdle() {
  const int64_t now = NowNs();
  const int64_t deadline = now - std::chrono::nanoseconds(timeout_).count();
  const int64_t token_period = std::chrono::nanoseconds(token_recheck_).count();
  const bool check_tokens = now - last_token_check_ns_ >= token_period;
  if (check_tokens) last_token_check_ns_ = now;
  std::vector<std::shared_ptr<State>> watched;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& [key, state] : streams_) {
      if (!state->cancelled) watched.push_back(state);
    }
  }
  // Without mutex_: a stream cancelled here may end (and drop its Watch) on this thread.
  for (const std::shared_ptr<State>& state : watched) {
    std::lock_guard<std::recursive_mutex> lock(state->cancel_mutex);
    if (!state->alive) continue;
    const int64_t since = state->waiting_since_ns;
    std::string why;
    if (since != 0 && since < deadline) {
      why = "idle for " + std::to_string(timeout_.count()) +
            " ms (forestmapd --stream-idle-timeout-s)";
    } else if (check_tokens) {
      why = Unauthenticated(*state->context);
    }
    if (why.empty()) continue;
    {
      std::lock_guard<std::mutex> guard(mutex_);
      state->cancelled = true;
    }
    LogLine(std::string(state->rpc) + ": cancelled a stream of " + state->context->peer() + ": " +
            why);
    state->context->TryCancel();
  }
}

}  // namespace forestmap::server
