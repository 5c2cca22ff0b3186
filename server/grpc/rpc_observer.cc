#include "server/grpc/rpc_observer.h"

#include <chrono>
#include <cstdio>
#include <mutex>
#include <random>
#include <unordered_map>

#include "proto/status_code_name.h"
#include "server/ops/logging.h"
#include "server/ops/metrics.h"

namespace forestmap::server {
namespace {

using grpc::experimental::InterceptionHookPoints;
using grpc::experimental::ServerRpcInfo;

constexpr std::string_view kServicePrefix = "/forestmap.v1.ForestMap/";
constexpr std::string_view kHealthPrefix = "/grpc.health.v1.Health/";

// "CreateMap" for our service, "grpc.health.v1.Health/Check" for others.
std::string RpcName(std::string_view method) {
  if (method.starts_with(kServicePrefix)) return std::string(method.substr(kServicePrefix.size()));
  if (method.starts_with("/")) method.remove_prefix(1);
  return std::string(method);
}

std::string NewRequestId() {
  thread_local std::mt19937_64 rng{std::random_device{}()};
  char text[33];
  std::snprintf(text, sizeof text, "%016llx%016llx", static_cast<unsigned long long>(rng()),
                static_cast<unsigned long long>(rng()));
  return text;
}

// A client's id is kept when it is 1..kMaxRequestIdBytes of visible ASCII.
bool UsableRequestId(std::string_view id) {
  if (id.empty() || id.size() > kMaxRequestIdBytes) return false;
  for (const char c : id) {
    if (c <= ' ' || c > '~' || c == '"') return false;
  }
  return true;
}

LogLevel LevelFor(grpc::StatusCode code, bool health) {
  if (health) return LogLevel::kDebug;
  switch (code) {
    case grpc::StatusCode::OK:
      return LogLevel::kInfo;
    case grpc::StatusCode::INTERNAL:
    case grpc::StatusCode::UNKNOWN:
    case grpc::StatusCode::DATA_LOSS:
      return LogLevel::kError;
    default:
      return LogLevel::kWarn;
  }
}

class RpcObserver;

// Which observer watches which call, for NoteCallMap from the handlers.
struct Registry {
  std::mutex mutex;
  std::unordered_map<const grpc::ServerContextBase*, RpcObserver*> calls;
};
Registry& Calls() {
  static Registry* registry = new Registry;  // never destroyed: calls may end during exit
  return *registry;
}

class RpcObserver final : public grpc::experimental::Interceptor {
 public:
  RpcObserver(ServerRpcInfo* info, Metrics* metrics)
      : context_(info->server_context()),
        metrics_(metrics),
        rpc_(RpcName(info->method())),
        health_(std::string_view(info->method()).starts_with(kHealthPrefix)),
        streaming_(info->type() != ServerRpcInfo::Type::UNARY &&
                   std::string_view(info->method()).starts_with(kServicePrefix)),
        start_(std::chrono::steady_clock::now()) {
    {
      std::lock_guard<std::mutex> lock(Calls().mutex);
      Calls().calls[context_] = this;
    }
    if (metrics_ != nullptr) metrics_->RpcStarted(rpc_, streaming_);
  }

  ~RpcObserver() override {
    // A call whose status was never sent (the server shut down under it).
    if (!finished_) Finish(grpc::Status(grpc::StatusCode::CANCELLED, "call ended without status"));
    std::lock_guard<std::mutex> lock(Calls().mutex);
    auto it = Calls().calls.find(context_);
    if (it != Calls().calls.end() && it->second == this) Calls().calls.erase(it);
  }

  void Intercept(grpc::experimental::InterceptorBatchMethods* methods) override {
    if (methods->QueryInterceptionHookPoint(InterceptionHookPoints::POST_RECV_INITIAL_METADATA)) {
      ReadRequestId(*methods->GetRecvInitialMetadata());
      peer_ = context_->peer();
    }
    if (methods->QueryInterceptionHookPoint(InterceptionHookPoints::PRE_SEND_INITIAL_METADATA)) {
      methods->GetSendInitialMetadata()->emplace(kRequestIdHeader, RequestId());
    }
    if (methods->QueryInterceptionHookPoint(InterceptionHookPoints::PRE_SEND_STATUS)) {
      Finish(methods->GetSendStatus());
    }
    methods->Proceed();
  }

  void Note(std::string_view map, int64_t token_id) {
    std::lock_guard<std::mutex> lock(mutex_);
    map_ = map;
    token_id_ = token_id;
  }

  std::string RequestId() {
    std::lock_guard<std::mutex> lock(mutex_);
    if (request_id_.empty()) request_id_ = NewRequestId();
    return request_id_;
  }

 private:
  void ReadRequestId(const std::multimap<grpc::string_ref, grpc::string_ref>& metadata) {
    const auto it = metadata.find(kRequestIdHeader);
    std::lock_guard<std::mutex> lock(mutex_);
    if (it != metadata.end()) {
      const std::string_view id(it->second.data(), it->second.size());
      if (UsableRequestId(id)) request_id_ = id;
    }
    if (request_id_.empty()) request_id_ = NewRequestId();
  }

  void Finish(const grpc::Status& status) {
    if (finished_) return;
    finished_ = true;
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    if (metrics_ != nullptr) metrics_->RpcFinished(rpc_, streaming_, status.error_code(), seconds);
    char ms[32];
    std::snprintf(ms, sizeof ms, "%.3f", seconds * 1e3);
    std::vector<LogField> fields = {{"rpc", rpc_}, {"request_id", RequestId()}};
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!map_.empty()) fields.push_back({"map", map_});
      if (token_id_ != 0) fields.push_back({"token", std::to_string(token_id_), true});
    }
    fields.push_back({"code", StatusCodeName(status.error_code())});
    fields.push_back({"ms", ms, true});
    if (!peer_.empty()) fields.push_back({"peer", peer_});
    if (!status.ok()) fields.push_back({"error", status.error_message()});
    Log(LevelFor(status.error_code(), health_), "rpc", fields);
  }

  grpc::ServerContextBase* context_;
  Metrics* metrics_;
  const std::string rpc_;
  const bool health_;
  const bool streaming_;
  const std::chrono::steady_clock::time_point start_;
  bool finished_ = false;  // only touched by gRPC's hooks and the destructor, one at a time
  std::string peer_;       // likewise
  std::mutex mutex_;       // request_id_, map_, token_id_ (handlers read them from their threads)
  std::string request_id_;
  std::string map_;
  int64_t token_id_ = 0;
};

}  // namespace

grpc::experimental::Interceptor* RpcObserverFactory::CreateServerInterceptor(ServerRpcInfo* info) {
  return new RpcObserver(info, metrics_);
}

void NoteCallMap(const grpc::ServerContextBase& context, std::string_view map, int64_t token_id) {
  std::lock_guard<std::mutex> lock(Calls().mutex);
  const auto it = Calls().calls.find(&context);
  if (it != Calls().calls.end()) it->second->Note(map, token_id);
}

}  // namespace forestmap::server
