// pg_fixture: the CTest fixture around one throwaway PostgreSQL cluster (tests/pg_fixture.h).
//   pg_fixture start STATE   starts a cluster, writes its URL (line 1) and directory (line 2)
//   pg_fixture stop STATE    stops the cluster STATE names, removes its directory and STATE
// `start` first stops a cluster a previous, interrupted run left behind in STATE.

#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>

#include "tests/pg_fixture.h"

namespace {

void StopFromState(const std::string& state) {
  std::ifstream in(state);
  std::string url, dir;
  if (!std::getline(in, url) || !std::getline(in, dir)) return;
  forestmap::testing::PostgresCluster::StopAndRemove(dir);
  std::filesystem::remove(state);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3 || (std::string(argv[1]) != "start" && std::string(argv[1]) != "stop")) {
    std::cerr << "usage: pg_fixture start|stop STATE_FILE\n";
    return 2;
  }
  const std::string state = argv[2];
  try {
    StopFromState(state);
    if (std::string(argv[1]) == "stop") return 0;
    auto cluster = forestmap::testing::PostgresCluster::Start();
    cluster->Detach();
    std::ofstream(state) << cluster->server_url() << "\n" << cluster->dir() << "\n";
    std::cout << "PostgreSQL test cluster at " << cluster->server_url() << " in " << cluster->dir()
              << "\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "pg_fixture: " << e.what() << "\n";
    return 1;
  }
}
