// The memory figure against a running forestmapd: UPLOADS clients each stream an
// upload of UPLOAD_TREES trees (with a species attribute) and hold it open, unfinished, while
// EXPORTS clients export a map of EXPORT_TREES trees, read one message and then stall. Every
// client has its own connection. Prints one JSON line when everything is open and held; the
// server's peak RSS is read from /proc by tests/bench/memory_bench.sh, which runs this.
//   memory_bench ADDRESS [UPLOADS=16] [UPLOAD_TREES=2000000] [EXPORTS=8] [EXPORT_TREES=1000000]
//                [HOLD_S=10]

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "forestmap/v1/forestmap_service.grpc.pb.h"

namespace {

using forestmap::v1::ForestMap;
namespace v1 = forestmap::v1;

constexpr int kTreesPerMessage = 5000;

// A stub on its own connection (a unique channel argument keeps gRPC from sharing one).
std::unique_ptr<ForestMap::Stub> Connect(const std::string& address, int id) {
  grpc::ChannelArguments arguments;
  arguments.SetInt("forestmap.bench.client", id);
  arguments.SetMaxReceiveMessageSize(64 << 20);
  return ForestMap::NewStub(
      grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), arguments));
}

// A chunk of `count` trees from number `first` on.
v1::UploadTreesRequest Message(int64_t first, int count) {
  v1::UploadTreesRequest message;
  for (int i = 0; i < count; ++i) {
    const int64_t k = first + i;
    v1::Tree* tree = message.mutable_chunk()->add_trees();
    tree->set_x(static_cast<double>(k % 2000) * 3.0);
    tree->set_y(static_cast<double>(k / 2000) * 3.0);
    tree->set_z(0.5);
    tree->set_dbh(0.3);
    (*tree->mutable_attributes())["species"] = "picea abies";
  }
  return message;
}

struct Upload {
  std::unique_ptr<ForestMap::Stub> stub;
  grpc::ClientContext context;
  v1::UploadTreesResponse response;
  std::unique_ptr<grpc::ClientWriter<v1::UploadTreesRequest>> writer;
};

// Sends `trees` trees; false when the server ended the stream.
bool Send(Upload& upload, const std::string& name, int64_t trees) {
  v1::UploadTreesRequest header;  // creates the map with its trees (create_map)
  header.mutable_header()->set_name(name);
  header.mutable_header()->set_create_map(true);
  if (!upload.writer->Write(header)) return false;
  for (int64_t sent = 0; sent < trees; sent += kTreesPerMessage) {
    const int count = static_cast<int>(std::min<int64_t>(kTreesPerMessage, trees - sent));
    if (!upload.writer->Write(Message(sent, count))) return false;
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr,
                 "usage: memory_bench ADDRESS [UPLOADS] [UPLOAD_TREES] [EXPORTS] "
                 "[EXPORT_TREES] [HOLD_S]\n");
    return 2;
  }
  const std::string address = argv[1];
  const int uploads = argc > 2 ? std::atoi(argv[2]) : 16;
  const int64_t upload_trees = argc > 3 ? std::atoll(argv[3]) : 2'000'000;
  const int exports = argc > 4 ? std::atoi(argv[4]) : 8;
  const int64_t export_trees = argc > 5 ? std::atoll(argv[5]) : 1'000'000;
  const int hold_s = argc > 6 ? std::atoi(argv[6]) : 10;
  const auto start = std::chrono::steady_clock::now();
  const auto seconds = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };

  {  // the exported map
    Upload upload;
    upload.stub = Connect(address, 0);
    upload.writer = upload.stub->UploadTrees(&upload.context, &upload.response);
    Send(upload, "exported", export_trees);
    upload.writer->WritesDone();
    const grpc::Status status = upload.writer->Finish();
    if (!status.ok()) {
      std::fprintf(stderr, "creating the exported map: %s\n", status.error_message().c_str());
      return 1;
    }
  }
  const double created_s = seconds();

  // Stalled exports: one message read, then nothing.
  std::vector<std::unique_ptr<ForestMap::Stub>> export_stubs;
  std::vector<std::unique_ptr<grpc::ClientContext>> export_contexts;
  std::vector<std::unique_ptr<grpc::ClientReader<v1::ExportTreesResponse>>> readers;
  for (int e = 0; e < exports; ++e) {
    export_stubs.push_back(Connect(address, 1000 + e));
    export_contexts.push_back(std::make_unique<grpc::ClientContext>());
    v1::ExportTreesRequest request;
    request.set_name("exported");
    readers.push_back(export_stubs.back()->ExportTrees(export_contexts.back().get(), request));
    v1::ExportTreesResponse first;
    if (!readers.back()->Read(&first)) {
      std::fprintf(stderr, "export %d: no first message\n", e);
      return 1;
    }
  }

  // Uploads, all at once, each held open after its last tree.
  std::vector<std::unique_ptr<Upload>> open(static_cast<size_t>(uploads));
  std::atomic<int> failed{0};
  std::vector<std::thread> threads;
  for (int u = 0; u < uploads; ++u) {
    open[static_cast<size_t>(u)] = std::make_unique<Upload>();
    threads.emplace_back([&, u] {
      Upload& upload = *open[static_cast<size_t>(u)];
      upload.stub = Connect(address, 2000 + u);
      upload.writer = upload.stub->UploadTrees(&upload.context, &upload.response);
      if (!Send(upload, "upload-" + std::to_string(u), upload_trees)) ++failed;
    });
  }
  for (std::thread& thread : threads) thread.join();
  const double sent_s = seconds();
  std::this_thread::sleep_for(std::chrono::seconds(hold_s));  // all open, all held

  std::printf(
      "{\"uploads\": %d, \"upload_trees\": %lld, \"exports\": %d, \"export_trees\": %lld, "
      "\"failed_uploads\": %d, \"export_map_s\": %.1f, \"uploads_sent_s\": %.1f}\n",
      uploads, static_cast<long long>(upload_trees), exports, static_cast<long long>(export_trees),
      failed.load(), created_s, sent_s);
  std::fflush(stdout);
  for (auto& upload : open) upload->context.TryCancel();  // nothing of them is committed
  for (auto& upload : open) upload->writer->Finish();
  for (auto& context : export_contexts) context->TryCancel();
  for (auto& reader : readers) reader->Finish();
  return failed.load() == 0 ? 0 : 1;
}
