#include "server/grpc/decode_guard.h"

#include <string>
#include <string_view>

#include "server/grpc/status.h"

namespace forestmap::server {
namespace {

using grpc::experimental::InterceptionHookPoints;
using grpc::experimental::ServerRpcInfo;

class DecodeGuard final : public grpc::experimental::Interceptor {
 public:
  explicit DecodeGuard(ServerRpcInfo* info)
      : method_(info->method()),
        single_request_(info->type() == ServerRpcInfo::Type::UNARY ||
                        info->type() == ServerRpcInfo::Type::SERVER_STREAMING) {}

  void Intercept(grpc::experimental::InterceptorBatchMethods* methods) override {
    if (single_request_ &&
        methods->QueryInterceptionHookPoint(InterceptionHookPoints::POST_RECV_MESSAGE) &&
        methods->GetRecvMessage() == nullptr) {
      undecodable_ = true;  // the one request message failed to parse
    }
    if (undecodable_ &&
        methods->QueryInterceptionHookPoint(InterceptionHookPoints::PRE_SEND_STATUS) &&
        methods->GetSendStatus().error_code() == grpc::StatusCode::UNIMPLEMENTED) {
      methods->ModifySendStatus(UndecodableRequest(method_));
    }
    methods->Proceed();
  }

 private:
  const std::string method_;
  const bool single_request_;
  bool undecodable_ = false;  // only touched by gRPC's hooks, one at a time
};

}  // namespace

grpc::experimental::Interceptor* DecodeGuardFactory::CreateServerInterceptor(ServerRpcInfo* info) {
  return new DecodeGuard(info);
}

}  // namespace forestmap::server
