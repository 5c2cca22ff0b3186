// `forestmap health`: asks every --server replica for its gRPC health (grpc.health.v1.Health,
// service "" = the whole server: SERVING once the database answers and the preloaded indexes are
// built; with --map, "map/NAME" = that preloaded map's index is warm) and prints one line each.
// Exit status 0 when all answer SERVING: the container HEALTHCHECK and the Kubernetes probes run
// it. The channel has the global TLS flags (the health service needs no token).

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <sstream>
#include <string>

#include "client/cli/cli_commands.h"
#include "grpc/health/v1/health.grpc.pb.h"

namespace forestmap::client {
namespace {

struct HealthOptions {
  double timeout_s = 2.0;  // s, deadline of each check
  std::string map;         // --map: that preloaded map's status instead of the server's
};

// "SERVING", or what went wrong.
std::string Check(const std::string& address, const HealthOptions& options,
                  const ClientOptions& client) {
  const auto channel = grpc::CreateChannel(address, ChannelCredentialsFor(client));
  const auto stub = grpc::health::v1::Health::NewStub(channel);
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() +
                       std::chrono::milliseconds(static_cast<int64_t>(options.timeout_s * 1000)));
  grpc::health::v1::HealthCheckRequest request;
  if (!options.map.empty()) request.set_service("map/" + options.map);
  grpc::health::v1::HealthCheckResponse response;
  const grpc::Status status = stub->Check(&context, request, &response);
  if (status.error_code() == grpc::StatusCode::NOT_FOUND && !options.map.empty()) {
    return "UNKNOWN: map '" + options.map + "' is not preloaded (forestmapd --preload)";
  }
  if (!status.ok()) return "unreachable: " + status.error_message();
  return grpc::health::v1::HealthCheckResponse::ServingStatus_Name(response.status());
}

void Run(const HealthOptions& options, const CliContext& context) {
  std::stringstream list(context.server);
  int unhealthy = 0;
  for (std::string address; std::getline(list, address, ',');) {
    const std::string state = Check(address, options, context.client);
    *context.out << address << " " << state << "\n";
    unhealthy += state != "SERVING";
  }
  if (unhealthy > 0) {
    throw CommandError(std::to_string(unhealthy) + " server(s) not SERVING");
  }
}

}  // namespace

void AddHealthCommand(CLI::App& app, CliContext& context) {
  auto options = std::make_shared<HealthOptions>();
  CLI::App* sub = app.add_subcommand(
      "health",
      "Check that forestmapd (each --server replica) is up and serving (gRPC health); "
      "exit status 0 when all are");
  sub->add_option("--timeout", options->timeout_s, "Deadline of each check, s")
      ->check(CLI::Range(0.01, 600.0))
      ->capture_default_str();
  sub->add_option("--map", options->map,
                  "Whether this map's relocalization index is built (a map forestmapd "
                  "preloads, --preload) instead of the whole server");
  sub->callback(
      [options, &context] { context.run = [options, &context] { Run(*options, context); }; });
}

}  // namespace forestmap::client
