// Logs and metrics of a real in-process server (127.0.0.1 port 0, SQLite file): the metrics
// endpoint is scraped over HTTP, checked by `promtool check metrics`, and its counters move with
// the calls; every RPC writes one structured log line with its request id, map, code and time.

#include <arpa/inet.h>
#include <grpcpp/generic/generic_stub.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <future>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <thread>
#include <utility>

#include "server/app/readiness.h"
#include "server/grpc/rpc_observer.h"
#include "server/grpc/server.h"
#include "server/grpc/service.h"
#include "server/http/metrics_http.h"
#include "server/ops/daemon.h"
#include "server/ops/logging.h"
#include "server/ops/metrics.h"
#include "server/ops/server_metrics.h"
#include "storage/sqlite/store.h"
#include "tests/server/http_get.h"
#include "tests/server/rpc_test_support.h"

namespace forestmap::server {
namespace {

namespace fs = std::filesystem;
constexpr auto kObservabilityDeadline = std::chrono::seconds(20);  // turns a hang into a failure

std::unique_ptr<grpc::ClientContext> TracedContext(const std::string& request_id = "") {
  auto context = std::make_unique<grpc::ClientContext>();
  context->set_deadline(std::chrono::system_clock::now() + kObservabilityDeadline);
  if (!request_id.empty()) context->AddMetadata(kRequestIdHeader, request_id);
  return context;
}

class ObservabilityTest : public ::testing::Test {
 protected:
  ObservabilityTest()
      : dir_(TempDir()),
        store_((dir_ / "maps.db").string()),
        service_(store_, ServiceOptions{}),
        runner_("127.0.0.1:0", service_, WithMetrics(&metrics_)),
        stub_(v1::ForestMap::NewStub(
            grpc::CreateChannel(runner_.address(), grpc::InsecureChannelCredentials()))) {
    AddServerMetrics(metrics_, service_.index_cache(), service_.answer_counts(),
                     (dir_ / "maps.db").string());
    AddProcessMetrics(metrics_);
    AddBuildInfo(metrics_);
    ReadinessOptions readiness;
    readiness.preload_all = true;
    readiness.interval = std::chrono::milliseconds(20);
    readiness_ = std::make_unique<Readiness>(
        store_, service_.index_cache(), readiness,
        [this](const std::string& name, bool serving, const std::string&) {
          runner_.SetServing(name, serving);
        });
    AddReadinessMetric(metrics_, *readiness_);
    // The first round (an empty SQLite store) takes microseconds; this only turns a hang into a
    // failure.
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    while (!readiness_->state().ready && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    http_ = std::make_unique<MetricsHttpServer>(
        "127.0.0.1:0", [this] { return metrics_.Render(); },
        [this] {
          const Readiness::State state = readiness_->state();
          return std::make_pair(state.ready, state.reason);
        });
  }
  ~ObservabilityTest() override {
    http_.reset();
    readiness_.reset();
    stub_.reset();
    fs::remove_all(dir_);
  }

  static fs::path TempDir() {
    std::string name = "observability_test_";
    name.append(std::to_string(getpid()));
    const fs::path dir = fs::temp_directory_path() / name;
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
  }
  static ServerOptions WithMetrics(Metrics* metrics) {
    ServerOptions options;
    options.metrics = metrics;
    return options;
  }

  std::string Scrape() {
    const test::HttpAnswer answer = test::HttpGet("127.0.0.1", http_->port(), "/metrics");
    EXPECT_TRUE(answer.ok) << "no answer from the metrics endpoint";
    EXPECT_EQ(answer.status, 200);
    EXPECT_NE(answer.content_type.find("text/plain"), std::string::npos) << answer.content_type;
    return answer.body;
  }

  // The value of the sample `series` (name with labels, exactly as exposed); NaN when absent.
  static double Sample(const std::string& text, const std::string& series) {
    std::istringstream lines(text);
    std::string line;
    while (std::getline(lines, line)) {
      if (line.rfind(series + " ", 0) == 0) return std::stod(line.substr(series.size() + 1));
    }
    return std::nan("");
  }

  // The sum of every sample whose series starts with `prefix`.
  static double SumOf(const std::string& text, const std::string& prefix) {
    std::istringstream lines(text);
    double sum = 0;
    for (std::string line; std::getline(lines, line);) {
      if (line.rfind(prefix, 0) == 0) sum += std::stod(line.substr(line.rfind(' ') + 1));
    }
    return sum;
  }

  v1::Map CreateMap(const std::string& name) {
    v1::CreateMapRequest request;
    request.set_name(name);
    v1::Map map;
    EXPECT_TRUE(stub_->CreateMap(TracedContext().get(), request, &map).ok());
    return map;
  }

  void Upload(const std::string& name) {
    v1::UploadTreesResponse response;
    auto context = TracedContext();
    auto writer = stub_->UploadTrees(context.get(), &response);
    v1::UploadTreesRequest request;
    const double plot[][2] = {{0, 0}, {7, 1}, {3, 9}, {12, 4}, {9, 13}, {15, 11}};
    int64_t id = 1;
    for (const auto& p : plot) {
      v1::Tree* tree = request.mutable_chunk()->add_trees();
      tree->set_id(id++);
      tree->set_x(p[0]);
      tree->set_y(p[1]);
    }
    ASSERT_TRUE(writer->Write(test::UploadHeader(name)));
    writer->Write(request);
    writer->WritesDone();
    ASSERT_TRUE(writer->Finish().ok());
  }

  fs::path dir_;
  storage::SqliteMapStore store_;
  ForestMapService service_;
  Metrics metrics_;
  ServerRunner runner_;
  std::unique_ptr<v1::ForestMap::Stub> stub_;
  std::unique_ptr<Readiness> readiness_;
  std::unique_ptr<MetricsHttpServer> http_;
};

TEST_F(ObservabilityTest, PromtoolAcceptsTheMetricsAndCountersMove) {
  const std::string before = Scrape();
  EXPECT_TRUE(
      std::isnan(Sample(before, R"(forestmap_rpc_requests_total{rpc="CreateMap",code="OK"})")));
  EXPECT_EQ(Sample(before, "forestmap_index_builds_total"), 0);

  CreateMap("plot-1");
  Upload("plot-1");
  v1::GetMapRequest missing;
  missing.set_name("no-such-map");
  v1::Map map;
  EXPECT_EQ(stub_->GetMap(TracedContext().get(), missing, &map).error_code(),
            grpc::StatusCode::NOT_FOUND);
  v1::RelocalizeRequest query;
  query.set_name("plot-1");
  for (const auto& p : {std::pair{0.0, 0.0}, {7.0, 1.0}, {3.0, 9.0}, {12.0, 4.0}}) {
    v1::DetectedTree* tree = query.add_trees();
    tree->mutable_position()->set_x(p.first);
    tree->mutable_position()->set_y(p.second);
  }
  v1::RelocalizeResponse answer;
  ASSERT_TRUE(stub_->Relocalize(TracedContext().get(), query, &answer).ok());

  // A tracking stream held open while scraping.
  auto track_context = TracedContext();
  auto track = stub_->Track(track_context.get());
  v1::TrackRequest header;
  header.mutable_header()->set_name("plot-1");
  ASSERT_TRUE(track->Write(header));
  v1::TrackRequest frame;
  *frame.mutable_frame()->mutable_trees() = query.trees();
  ASSERT_TRUE(track->Write(frame));
  v1::TrackResponse tracked;
  ASSERT_TRUE(track->Read(&tracked));

  const std::string during = Scrape();
  const std::string file = (dir_ / "metrics.txt").string();
  std::ofstream(file) << during;
  const std::string promtool = "promtool check metrics < " + file;
  EXPECT_EQ(std::system(promtool.c_str()), 0) << during;

  EXPECT_EQ(Sample(during, R"(forestmap_rpc_requests_total{rpc="CreateMap",code="OK"})"), 1);
  EXPECT_EQ(Sample(during, R"(forestmap_rpc_requests_total{rpc="UploadTrees",code="OK"})"), 1);
  EXPECT_EQ(Sample(during, R"(forestmap_rpc_requests_total{rpc="GetMap",code="NOT_FOUND"})"), 1);
  EXPECT_EQ(Sample(during, R"(forestmap_rpc_duration_seconds_count{rpc="Relocalize"})"), 1);
  EXPECT_EQ(Sample(during, R"(forestmap_rpc_duration_seconds_bucket{rpc="Relocalize",le="+Inf"})"),
            1);
  EXPECT_GT(Sample(during, R"(forestmap_rpc_duration_seconds_sum{rpc="Relocalize"})"), 0);
  EXPECT_EQ(Sample(during, "forestmap_open_streams"), 1);
  EXPECT_EQ(Sample(during, R"(forestmap_rpc_in_flight{rpc="Track"})"), 1);
  EXPECT_EQ(Sample(during, "forestmap_index_builds_total"), 1);
  EXPECT_GT(Sample(during, "forestmap_index_build_seconds_total"), 0);
  EXPECT_EQ(Sample(during, "forestmap_index_cache_maps"), 1);
  EXPECT_GT(Sample(during, "forestmap_index_cache_bytes"), 0);
  EXPECT_GT(Sample(during, "forestmap_database_bytes"), 0);
  EXPECT_GT(Sample(during, R"(forestmap_index_bytes{map="plot-1"})"), 0);
  // One answer of each kind counted under its outcome, whichever it was.
  EXPECT_EQ(SumOf(during, "forestmap_relocalizations_total{status=\""), 1);
  EXPECT_EQ(SumOf(during, "forestmap_track_frames_total{state=\""), 1);
  EXPECT_EQ(Sample(during, "forestmap_ready"), 1);
  EXPECT_EQ(SumOf(during, "forestmap_build_info{version=\""), 1);
  EXPECT_GT(Sample(during, "process_resident_memory_bytes"), 1 << 20);
  EXPECT_GT(Sample(during, "process_open_fds"), 2);
  EXPECT_GT(Sample(during, "process_max_fds"), Sample(during, "process_open_fds"));
  EXPECT_GT(Sample(during, "process_cpu_seconds_total"), 0);
  EXPECT_GT(Sample(during, "process_start_time_seconds"), 1.7e9);

  ASSERT_TRUE(track->WritesDone());
  while (track->Read(&tracked)) {
  }
  ASSERT_TRUE(track->Finish().ok());
  CreateMap("plot-2");
  const std::string after = Scrape();
  EXPECT_EQ(Sample(after, R"(forestmap_rpc_requests_total{rpc="CreateMap",code="OK"})"), 2);
  EXPECT_EQ(Sample(after, R"(forestmap_rpc_requests_total{rpc="Track",code="OK"})"), 1);
  EXPECT_EQ(Sample(after, "forestmap_open_streams"), 0);
}

// Each answer counted under its own labels: a query of 2 trees is NOT_FOUND for TOO_FEW_TREES, a
// frame without trees is LOST; the other answers under the status and state they had.
TEST_F(ObservabilityTest, RelocalizationsByStatusAndReasonTrackFramesByState) {
  CreateMap("plot-1");
  Upload("plot-1");
  const auto lower = [](std::string name, const std::string& prefix) {
    name = name.substr(prefix.size());
    std::transform(name.begin(), name.end(), name.begin(), ::tolower);
    return name;
  };
  v1::RelocalizeRequest plot;
  plot.set_name("plot-1");
  for (const auto& p : {std::pair{0.0, 0.0}, {7.0, 1.0}, {3.0, 9.0}, {12.0, 4.0}}) {
    v1::DetectedTree* tree = plot.add_trees();
    tree->mutable_position()->set_x(p.first);
    tree->mutable_position()->set_y(p.second);
  }
  v1::RelocalizeRequest few = plot;
  few.mutable_trees()->DeleteSubrange(2, 2);  // 2 trees: nothing to match
  v1::RelocalizeResponse too_few, answer;
  ASSERT_TRUE(stub_->Relocalize(TracedContext().get(), few, &too_few).ok());
  ASSERT_EQ(too_few.reason(), v1::RelocalizeResponse::REASON_TOO_FEW_TREES);
  ASSERT_TRUE(stub_->Relocalize(TracedContext().get(), plot, &answer).ok());

  auto track_context = TracedContext();
  auto track = stub_->Track(track_context.get());
  v1::TrackRequest header;
  header.mutable_header()->set_name("plot-1");
  ASSERT_TRUE(track->Write(header));
  std::vector<std::string> states;
  for (const bool empty : {true, false}) {
    v1::TrackRequest frame;
    frame.mutable_frame();  // an empty frame: nothing seen
    if (!empty) *frame.mutable_frame()->mutable_trees() = plot.trees();
    ASSERT_TRUE(track->Write(frame));
    v1::TrackResponse tracked;
    ASSERT_TRUE(track->Read(&tracked));
    states.push_back(lower(v1::TrackResponse::State_Name(tracked.state()), "STATE_"));
  }
  EXPECT_EQ(states[0], "lost");
  ASSERT_TRUE(track->WritesDone());
  ASSERT_TRUE(track->Finish().ok());

  const std::string text = Scrape();
  const std::string file = (dir_ / "metrics.txt").string();
  std::ofstream(file) << text;
  EXPECT_EQ(std::system(("promtool check metrics < " + file).c_str()), 0) << text;
  const std::string status = lower(v1::RelocalizeResponse::Status_Name(answer.status()), "STATUS_");
  EXPECT_EQ(SumOf(text, "forestmap_relocalizations_total{"), 2) << text;
  EXPECT_EQ(
      Sample(text, R"(forestmap_relocalizations_total{status="not_found",reason="too_few_trees"})"),
      status == "not_found" && answer.reason() == too_few.reason() ? 2 : 1)
      << text;
  EXPECT_GE(SumOf(text, "forestmap_relocalizations_total{status=\"" + status + "\",reason=\""), 1)
      << text;
  EXPECT_EQ(SumOf(text, "forestmap_track_frames_total{"), 2) << text;
  EXPECT_EQ(Sample(text, "forestmap_track_frames_total{state=\"lost\"}"),
            states[1] == "lost" ? 2 : 1)
      << text;
  EXPECT_GE(Sample(text, "forestmap_track_frames_total{state=\"" + states[1] + "\"}"), 1) << text;
}

TEST_F(ObservabilityTest, TheMetricsPortAnswersLivenessReadinessAndAnIndex) {
  for (const auto& [path, body] :
       {std::pair{"/healthz", "ok"}, {"/readyz", "ready"}, {"/", "/metrics"}}) {
    const test::HttpAnswer answer = test::HttpGet("127.0.0.1", http_->port(), path);
    EXPECT_EQ(answer.status, 200) << path;
    EXPECT_NE(answer.body.find(body), std::string::npos) << path << ": " << answer.body;
  }
  EXPECT_EQ(test::HttpGet("127.0.0.1", http_->port(), "/nothing").status, 404);
}

// Connections that connect and send nothing hold a worker each until their read timeout; 50 of
// them stalled cpp-httplib's 8 workers for ~30 s. The endpoint answers another client (here the
// idle connections come from 127.0.0.2) while they are held (the 10 s bound only turns a stall
// into a failure).
TEST_F(ObservabilityTest, HalfOpenConnectionsDoNotStallTheMetricsPort) {
  std::vector<int> idle;
  for (int i = 0; i < 50; ++i) {
    const int sock = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in from{};
    from.sin_family = AF_INET;
    inet_pton(AF_INET, "127.0.0.2", &from.sin_addr);
    ASSERT_EQ(bind(sock, reinterpret_cast<sockaddr*>(&from), sizeof(from)), 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(static_cast<uint16_t>(http_->port()));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ASSERT_EQ(connect(sock, reinterpret_cast<sockaddr*>(&address), sizeof(address)), 0);
    idle.push_back(sock);
  }
  const auto start = std::chrono::steady_clock::now();
  auto answer = std::async(
      std::launch::async, [this] { return test::HttpGet("127.0.0.1", http_->port(), "/healthz"); });
  ASSERT_EQ(answer.wait_for(std::chrono::seconds(10)), std::future_status::ready);
  EXPECT_EQ(answer.get().status, 200);
  std::printf(
      "answered in %.0f ms beside 50 idle connections\n",
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
  for (const int sock : idle) close(sock);
}

// Calls a method path through a generic stub; returns the status the server (or the channel)
// gave it.
grpc::StatusCode CallRawMethod(grpc::GenericStub& stub, const std::string& method) {
  grpc::CompletionQueue queue;
  auto context = TracedContext();
  grpc::ByteBuffer request, response;
  grpc::Status status;
  std::unique_ptr<grpc::GenericClientAsyncResponseReader> call =
      stub.PrepareUnaryCall(context.get(), method, request, &queue);
  call->StartCall();
  call->Finish(&response, &status, reinterpret_cast<void*>(1));
  void* tag = nullptr;
  bool ok = false;
  EXPECT_TRUE(queue.Next(&tag, &ok));
  queue.Shutdown();
  while (queue.Next(&tag, &ok)) {
  }
  return status.error_code();
}

TEST_F(ObservabilityTest, UnknownMethodNamesNeitherForgeMetricsNorGrowThePage) {
  CreateMap("plot-1");
  const std::string before = Scrape();
  grpc::GenericStub stub(
      grpc::CreateChannel(runner_.address(), grpc::InsecureChannelCredentials()));
  // Names that would close the label and start lines of their own if copied into the page.
  const std::vector<std::string> forged = {
      "/x\"} 1\nfake_metric 42\n#",
      "/forestmap.v1.ForestMap/NoSuchRpc\"} 7\nfake_metric 42",
      "/forestmap.v1.ForestMap/Create\\Map\"",
      "/grpc.health.v1.Health/Nope",
  };
  int reached = 0;
  for (const std::string& method : forged) {
    reached += CallRawMethod(stub, method) == grpc::StatusCode::UNIMPLEMENTED;
  }
  constexpr int kJunkNames = 300;
  for (int i = 0; i < kJunkNames; ++i) {
    const std::string method = "/junk.Service" + std::to_string(i) + "/Method" + std::to_string(i);
    ASSERT_EQ(CallRawMethod(stub, method), grpc::StatusCode::UNIMPLEMENTED) << method;
    ++reached;
  }
  const std::string after = Scrape();
  const std::string file = (dir_ / "metrics.txt").string();
  std::ofstream(file) << after;
  const std::string promtool = "promtool check metrics < " + file;
  EXPECT_EQ(std::system(promtool.c_str()), 0) << after.substr(0, 4000);
  EXPECT_EQ(after.find("fake_metric"), std::string::npos);
  EXPECT_EQ(after.find("junk.Service"), std::string::npos);
  EXPECT_EQ(after.find("NoSuchRpc"), std::string::npos);
  // Every unknown method is counted under one label: the page grew by one series set, not 300.
  EXPECT_EQ(Sample(after, R"(forestmap_rpc_requests_total{rpc="unknown",code="UNIMPLEMENTED"})"),
            reached);
  EXPECT_LT(after.size(), before.size() + 4096) << "the page grew with the junk names";
  EXPECT_EQ(Sample(after, R"(forestmap_rpc_requests_total{rpc="CreateMap",code="OK"})"), 1);
}

TEST(MetricsText, EscapesAndBoundsLabelValuesFromOutside) {
  Metrics metrics;
  const std::string hostile = "a\\b\"c\nd";
  metrics.RpcStarted(hostile, false);
  metrics.RpcFinished(hostile, false, grpc::StatusCode::OK, 0.01);
  metrics.RpcStarted(std::string(10'000, 'x'), false);
  const std::string page = metrics.Render();
  EXPECT_NE(page.find(R"(rpc="a\\b\"c\nd")"), std::string::npos) << page;
  EXPECT_EQ(page.find(std::string(1000, 'x')), std::string::npos) << "an unbounded label";
  std::istringstream lines(page);
  std::string line;
  while (std::getline(lines, line)) {
    EXPECT_TRUE(line.starts_with("forestmap_") || line.starts_with("# ")) << line;
  }
}

TEST_F(ObservabilityTest, EveryRpcLogsOneJsonLineWithItsRequestId) {
  ConfigureLogging({LogFormat::kJson, LogLevel::kInfo});
  CreateMap("plot-1");
  ::testing::internal::CaptureStderr();
  v1::GetMapRequest request;
  request.set_name("plot-1");
  v1::Map map;
  auto with_id = TracedContext("client-req-42");
  ASSERT_TRUE(stub_->GetMap(with_id.get(), request, &map).ok());
  request.set_name("nope");
  auto without_id = TracedContext();
  EXPECT_FALSE(stub_->GetMap(without_id.get(), request, &map).ok());
  const std::string log = ::testing::internal::GetCapturedStderr();
  ConfigureLogging({});

  // The id goes back to the client in the initial metadata: its own, or a generated one.
  const auto echoed = with_id->GetServerInitialMetadata().find(kRequestIdHeader);
  ASSERT_NE(echoed, with_id->GetServerInitialMetadata().end());
  EXPECT_EQ(std::string(echoed->second.data(), echoed->second.size()), "client-req-42");
  const auto generated = without_id->GetServerInitialMetadata().find(kRequestIdHeader);
  ASSERT_NE(generated, without_id->GetServerInitialMetadata().end());
  const std::string generated_id(generated->second.data(), generated->second.size());
  EXPECT_EQ(generated_id.size(), 32u);

  std::vector<nlohmann::json> lines;
  std::istringstream stream(log);
  std::string line;
  while (std::getline(stream, line)) lines.push_back(nlohmann::json::parse(line));  // valid JSON
  ASSERT_EQ(lines.size(), 2u) << log;
  const std::regex iso_time(R"(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}Z)");
  for (const nlohmann::json& entry : lines) {
    EXPECT_TRUE(std::regex_match(entry.at("time").get<std::string>(), iso_time)) << entry;
    EXPECT_EQ(entry.at("msg"), "rpc");
    EXPECT_EQ(entry.at("rpc"), "GetMap");
    EXPECT_TRUE(entry.at("ms").is_number());
    EXPECT_GE(entry.at("ms").get<double>(), 0);
  }
  EXPECT_EQ(lines[0].at("level"), "info");
  EXPECT_EQ(lines[0].at("request_id"), "client-req-42");
  EXPECT_EQ(lines[0].at("map"), "plot-1");
  EXPECT_EQ(lines[0].at("code"), "OK");
  EXPECT_EQ(lines[1].at("level"), "warning");
  EXPECT_EQ(lines[1].at("request_id"), generated_id);
  EXPECT_EQ(lines[1].at("map"), "nope");
  EXPECT_EQ(lines[1].at("code"), "NOT_FOUND");
  EXPECT_NE(lines[1].at("error").get<std::string>().find("nope"), std::string::npos);
}

TEST(Logging, TextLinesQuoteValuesAndJsonEscapes) {
  EXPECT_EQ(JsonEscape("a\"b\\c\n\x01\xff"), "a\\\"b\\\\c\\u000a\\u0001\\u00ff");
  EXPECT_EQ(ParseLogLevel("warn"), LogLevel::kWarn);
  EXPECT_THROW(ParseLogLevel("loud"), std::invalid_argument);
  EXPECT_THROW(ParseLogFormat("xml"), std::invalid_argument);
  ::testing::internal::CaptureStderr();
  ConfigureLogging({LogFormat::kText, LogLevel::kWarn});
  Log(LogLevel::kInfo, "dropped below the level");
  Log(LogLevel::kWarn, "kept", {{"map", "plot 1"}, {"code", "OK"}});
  const std::string log = ::testing::internal::GetCapturedStderr();
  ConfigureLogging({});
  EXPECT_EQ(log.find("dropped"), std::string::npos);
  EXPECT_NE(log.find(" warning kept map=\"plot 1\" code=OK"), std::string::npos) << log;
}

TEST(ExposedListener, WarnsBeyondLoopbackWithoutTlsOrTokens) {
  ::testing::internal::CaptureStderr();
  EXPECT_FALSE(WarnIfExposed("127.0.0.1:50051", false, false));
  EXPECT_TRUE(WarnIfExposed("0.0.0.0:50051", false, false));
  EXPECT_TRUE(WarnIfExposed("0.0.0.0:50051", true, false));
  EXPECT_FALSE(WarnIfExposed("0.0.0.0:50051", true, true));
  EXPECT_FALSE(WarnIfExposed("0.0.0.0:8080", true, true, Listener::kWebPage));  // HTTPS
  EXPECT_FALSE(WarnIfExposed("127.0.0.1:9464", false, false, Listener::kMetrics));
  EXPECT_FALSE(WarnIfExposed("0.0.0.0:9464", true, false, Listener::kMetrics));  // no tokens on it
  EXPECT_TRUE(WarnIfExposed("0.0.0.0:9464", false, true, Listener::kMetrics));
  const std::string log = ::testing::internal::GetCapturedStderr();
  EXPECT_NE(log.find("WITHOUT TLS"), std::string::npos) << log;
  EXPECT_NE(log.find("WITHOUT TOKENS"), std::string::npos) << log;
  EXPECT_NE(log.find("WARNING: metrics port listening beyond loopback WITHOUT TLS"),
            std::string::npos)
      << log;
}

}  // namespace
}  // namespace forestmap::server
