// Tokens and roles end to end: an in-process server on 127.0.0.1 port 0 with a token store; every
// RPC called without a token, with an unknown one, with one of the wrong role (or map) and with
// the right one.

#include "server/ops/auth.h"

#include <google/protobuf/descriptor.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <chrono>
#include <functional>
#include <memory>
#include <string>

#include "forestmap/v1/forestmap_service.pb.h"
#include "proto/status_code_name.h"
#include "server/grpc/server.h"
#include "server/grpc/service.h"
#include "storage/sqlite/store.h"
#include "storage/token_store.h"
#include "tests/server/rpc_test_support.h"

namespace forestmap::server {
namespace {

using storage::Role;
using Stub = v1::ForestMap::Stub;

constexpr auto kCallDeadline = std::chrono::seconds(20);  // turns a hang into a failure
constexpr const char* kMap = "plot-a";                    // has trees, history, observations

std::unique_ptr<grpc::ClientContext> Context(const std::string& token) {
  auto context = std::make_unique<grpc::ClientContext>();
  context->set_deadline(std::chrono::system_clock::now() + kCallDeadline);
  if (!token.empty()) context->AddMetadata("authorization", "Bearer " + token);
  return context;
}

v1::Tree Tree(int64_t id, double x, double y) {
  v1::Tree tree;
  tree.set_id(id);
  tree.set_x(x);
  tree.set_y(y);
  // With z: Observe on a map of survey trees without z fails today ("NOT NULL constraint
  // failed: observations.sensor_z", the survey observation's sensor position is NaN); not an
  // auth matter, reported separately.
  tree.set_z(0);
  tree.set_dbh(0.3);
  return tree;
}

// Trees of a small irregular plot; queries use the same positions (identity pose).
constexpr double kPlot[][2] = {{0, 0}, {7, 1}, {3, 9}, {12, 4}, {9, 13}, {15, 11}, {5, 17}};

void AddQueryTrees(google::protobuf::RepeatedPtrField<v1::DetectedTree>* trees) {
  for (const auto& p : kPlot) {
    v1::DetectedTree* tree = trees->Add();
    tree->mutable_position()->set_x(p[0]);
    tree->mutable_position()->set_y(p[1]);
    tree->mutable_position()->set_z(0);
    tree->set_dbh(0.3);
  }
}

// One call of each RPC, as a function of the token; returns the status.
using Call = std::function<grpc::Status(Stub&, const std::string& token)>;

grpc::Status CreateMap(Stub& stub, const std::string& token, const std::string& name) {
  v1::CreateMapRequest request;
  request.set_name(name);
  v1::Map map;
  return stub.CreateMap(Context(token).get(), request, &map);
}

grpc::Status Upload(Stub& stub, const std::string& token, const std::string& map, int64_t id0) {
  v1::UploadTreesResponse response;
  auto context = Context(token);
  auto writer = stub.UploadTrees(context.get(), &response);
  v1::UploadTreesRequest request;
  for (size_t i = 0; i < std::size(kPlot); ++i) {
    *request.mutable_chunk()->add_trees() =
        Tree(id0 + static_cast<int64_t>(i), kPlot[i][0], kPlot[i][1]);
  }
  if (writer->Write(test::UploadHeader(map))) writer->Write(request);
  writer->WritesDone();
  return writer->Finish();
}

grpc::Status Track(Stub& stub, const std::string& token) {
  auto context = Context(token);
  auto stream = stub.Track(context.get());
  v1::TrackRequest header;
  header.mutable_header()->set_name(kMap);
  v1::TrackRequest request;
  request.mutable_frame()->set_frame_id(1);
  AddQueryTrees(request.mutable_frame()->mutable_trees());
  if (stream->Write(header)) stream->Write(request);
  stream->WritesDone();
  v1::TrackResponse response;
  while (stream->Read(&response)) {
  }
  return stream->Finish();
}

grpc::Status Observe(Stub& stub, const std::string& token) {
  v1::ObserveRequest request;
  request.set_name(kMap);
  request.set_source("auth-test");
  v1::ObservationFrame* frame = request.add_frames();
  frame->set_frame_id(1);
  frame->mutable_map_from_sensor()->mutable_rotation()->set_w(1);  // identity
  AddQueryTrees(frame->mutable_trees());
  v1::ObserveResponse response;
  return stub.Observe(Context(token).get(), request, &response);
}

struct RpcCase {
  std::string rpc;
  Role role;
  Call call;
};

// In an order where each right-role call can succeed (RemoveSource after Observe, ...).
std::vector<RpcCase> AllRpcs() {
  std::vector<RpcCase> cases;
  static int created = 0;
  cases.push_back({"CreateMap", Role::kAdmin, [](Stub& stub, const std::string& token) {
                     return CreateMap(stub, token, "plot-new-" + std::to_string(++created));
                   }});
  cases.push_back({"ListMaps", Role::kRead, [](Stub& stub, const std::string& token) {
                     v1::ListMapsResponse response;
                     return stub.ListMaps(Context(token).get(), {}, &response);
                   }});
  cases.push_back({"GetMap", Role::kRead, [](Stub& stub, const std::string& token) {
                     v1::GetMapRequest request;
                     request.set_name(kMap);
                     v1::Map map;
                     return stub.GetMap(Context(token).get(), request, &map);
                   }});
  cases.push_back({"UploadTrees", Role::kWrite, [](Stub& stub, const std::string& token) {
                     static int64_t next_id = 1000;
                     next_id += 100;
                     return Upload(stub, token, kMap, next_id);
                   }});
  cases.push_back({"ExportTrees", Role::kRead, [](Stub& stub, const std::string& token) {
                     v1::ExportTreesRequest request;
                     request.set_name(kMap);
                     auto context = Context(token);
                     auto reader = stub.ExportTrees(context.get(), request);
                     v1::ExportTreesResponse response;
                     while (reader->Read(&response)) {
                     }
                     return reader->Finish();
                   }});
  cases.push_back({"Relocalize", Role::kRead, [](Stub& stub, const std::string& token) {
                     v1::RelocalizeRequest request;
                     request.set_name(kMap);
                     AddQueryTrees(request.mutable_trees());
                     v1::RelocalizeResponse response;
                     return stub.Relocalize(Context(token).get(), request, &response);
                   }});
  cases.push_back({"Track", Role::kRead, Track});
  cases.push_back({"Observe", Role::kWrite, Observe});
  cases.push_back({"ListVersions", Role::kRead, [](Stub& stub, const std::string& token) {
                     v1::ListVersionsRequest request;
                     request.set_name(kMap);
                     v1::ListVersionsResponse response;
                     return stub.ListVersions(Context(token).get(), request, &response);
                   }});
  cases.push_back({"RemoveSource", Role::kWrite, [](Stub& stub, const std::string& token) {
                     v1::RemoveSourceRequest request;
                     request.set_name(kMap);
                     request.set_source("auth-test");
                     v1::RemoveSourceResponse response;
                     return stub.RemoveSource(Context(token).get(), request, &response);
                   }});
  cases.push_back({"RestoreVersion", Role::kAdmin, [](Stub& stub, const std::string& token) {
                     v1::RestoreVersionRequest request;
                     request.set_name(kMap);
                     request.set_version(2);  // after the first upload
                     v1::RestoreVersionResponse response;
                     return stub.RestoreVersion(Context(token).get(), request, &response);
                   }});
  cases.push_back({"DeleteMap", Role::kAdmin, [](Stub& stub, const std::string& token) {
                     v1::DeleteMapRequest request;
                     request.set_name("plot-doomed");
                     v1::DeleteMapResponse response;
                     return stub.DeleteMap(Context(token).get(), request, &response);
                   }});
  return cases;
}

class AuthTest : public ::testing::Test {
 protected:
  AuthTest()
      : tokens_(":memory:"),
        authorizer_(&tokens_),
        service_(store_, WithAuthorizer(&authorizer_)),
        runner_("127.0.0.1:0", service_),
        stub_(v1::ForestMap::NewStub(
            grpc::CreateChannel(runner_.address(), grpc::InsecureChannelCredentials()))) {}

  static ServiceOptions WithAuthorizer(const Authorizer* authorizer) {
    ServiceOptions options;
    options.authorizer = authorizer;
    return options;
  }

  // plot-a with trees (version 2), plot-doomed to delete; made while the server is still open.
  void SetUpMaps() {
    ASSERT_TRUE(CreateMap(*stub_, "", kMap).ok());
    ASSERT_TRUE(Upload(*stub_, "", kMap, 1).ok());
    ASSERT_TRUE(CreateMap(*stub_, "", "plot-doomed").ok());
    ASSERT_TRUE(CreateMap(*stub_, "", "other").ok());
  }

  storage::SqliteMapStore store_{":memory:"};
  storage::TokenStore tokens_;
  Authorizer authorizer_;
  ForestMapService service_;
  ServerRunner runner_;
  std::unique_ptr<Stub> stub_;
};

TEST_F(AuthTest, WithoutAnyTokenTheServerIsOpen) {
  SetUpMaps();
  for (const RpcCase& rpc : AllRpcs()) {
    const grpc::Status status = rpc.call(*stub_, "");
    EXPECT_TRUE(status.ok()) << rpc.rpc << ": " << status.error_message();
  }
}

TEST_F(AuthTest, EveryRpcWithoutTokenWrongTokenWrongRoleAndRightRole) {
  SetUpMaps();
  const std::string admin = tokens_.Create("plot-*", Role::kAdmin).secret;
  const std::string write = tokens_.Create("plot-*", Role::kWrite).secret;
  const std::string read = tokens_.Create("plot-*", Role::kRead).secret;
  const std::string admin_elsewhere = tokens_.Create("other", Role::kAdmin).secret;
  const std::string revoked = tokens_.Create("*", Role::kAdmin).secret;
  ASSERT_TRUE(tokens_.Revoke(tokens_.Find(revoked)->id));
  const std::map<Role, std::string> right = {
      {Role::kRead, read}, {Role::kWrite, write}, {Role::kAdmin, admin}};

  for (const RpcCase& rpc : AllRpcs()) {
    SCOPED_TRACE(rpc.rpc);
    grpc::Status status = rpc.call(*stub_, "");
    EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAUTHENTICATED) << status.error_message();
    EXPECT_NE(status.error_message().find("requires a token"), std::string::npos);
    status = rpc.call(*stub_, "fmt_0123456789abcdef");
    EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAUTHENTICATED) << status.error_message();
    status = rpc.call(*stub_, revoked);
    EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAUTHENTICATED) << status.error_message();
    if (rpc.role != Role::kRead) {  // one role below the one needed
      const Role weaker = rpc.role == Role::kAdmin ? Role::kWrite : Role::kRead;
      status = rpc.call(*stub_, right.at(weaker));
      EXPECT_EQ(status.error_code(), grpc::StatusCode::PERMISSION_DENIED) << status.error_message();
      EXPECT_NE(
          status.error_message().find(std::string("needs role ") + storage::RoleName(rpc.role)),
          std::string::npos)
          << status.error_message();
    }
    if (rpc.rpc != "ListMaps") {  // admin, but of another map
      status = rpc.call(*stub_, admin_elsewhere);
      EXPECT_EQ(status.error_code(), grpc::StatusCode::PERMISSION_DENIED) << status.error_message();
    }
    status = rpc.call(*stub_, right.at(rpc.role));
    EXPECT_TRUE(status.ok()) << StatusCodeName(status.error_code()) << ": "
                             << status.error_message();
  }
}

TEST_F(AuthTest, ListMapsShowsOnlyTheMapsATokenCanRead) {
  SetUpMaps();
  const std::string other = tokens_.Create("other", Role::kRead).secret;
  v1::ListMapsResponse response;
  ASSERT_TRUE(stub_->ListMaps(Context(other).get(), {}, &response).ok());
  ASSERT_EQ(response.maps_size(), 1);
  EXPECT_EQ(response.maps(0).name(), "other");
  const std::string all = tokens_.Create("*", Role::kRead).secret;
  ASSERT_TRUE(stub_->ListMaps(Context(all).get(), {}, &response).ok());
  EXPECT_EQ(response.maps_size(), 3);
}

TEST_F(AuthTest, RevokingEveryTokenKeepsTheServerClosed) {
  SetUpMaps();
  const storage::NewToken token = tokens_.Create("*", Role::kAdmin);
  v1::ListMapsResponse response;
  EXPECT_TRUE(stub_->ListMaps(Context(token.secret).get(), {}, &response).ok());
  ASSERT_TRUE(tokens_.Revoke(token.record.id));
  EXPECT_EQ(stub_->ListMaps(Context("").get(), {}, &response).error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(stub_->ListMaps(Context(token.secret).get(), {}, &response).error_code(),
            grpc::StatusCode::UNAUTHENTICATED);
}

TEST_F(AuthTest, AMalformedAuthorizationHeaderIsUnauthenticated) {
  SetUpMaps();
  tokens_.Create("*", Role::kAdmin);
  auto context = Context("");
  context->AddMetadata("authorization", "Basic dXNlcjpwYXNz");
  v1::ListMapsResponse response;
  const grpc::Status status = stub_->ListMaps(context.get(), {}, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_NE(status.error_message().find("Bearer"), std::string::npos);
}

// A new RPC without an entry in the role table would be refused to everyone: this catches it.
TEST(AuthRoles, EveryServiceMethodHasARole) {
  // Nothing else references forestmap_service.pb.o (the service file has no messages): without
  // this the linker drops it and its descriptor never reaches the generated pool.
  const void* volatile table = &descriptor_table_forestmap_2fv1_2fforestmap_5fservice_2eproto;
  ASSERT_NE(table, nullptr);
  const google::protobuf::ServiceDescriptor* service =
      google::protobuf::DescriptorPool::generated_pool()->FindServiceByName(
          v1::ForestMap::service_full_name());
  ASSERT_NE(service, nullptr);
  for (int i = 0; i < service->method_count(); ++i) {
    EXPECT_TRUE(RequiredRole(service->method(i)->name()).has_value())
        << service->method(i)->name() << " has no role in server/ops/auth.cc";
  }
  EXPECT_EQ(RequiredRole("CreateMap"), Role::kAdmin);
  EXPECT_EQ(RequiredRole("Observe"), Role::kWrite);
  EXPECT_EQ(RequiredRole("Relocalize"), Role::kRead);
  EXPECT_FALSE(RequiredRole("NoSuchRpc").has_value());
}

}  // namespace
}  // namespace forestmap::server
