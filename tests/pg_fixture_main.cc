// pg_fixture: the CTest fixture around one throwaway PostgreSQL cluster (tests/pg_fixture.h).
//   pg_fixture start STATE   starts a cluster, writes its URL (line 1) and directory (line 2)
//                            to STATE.<pid of the CTest run> (RunStateFile)
//   pg_fixture stop STATE    stops the cluster of this run, removes its directory and state file
// Each CTest run has its own cluster: a second run in the same build folder (a quick `ctest -R`
// beside a full run) used to stop the first run's cluster at its start and its end, failing the
// first run's PostgreSQL tests of that moment. `start` also stops the clusters that runs which
// are gone (interrupted) left behind.

#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>

#include "tests/pg_fixture.h"

namespace {

namespace fs = std::filesystem;

void StopFromState(const std::string& state) {
  std::ifstream in(state);
  std::string url, dir;
  if (std::getline(in, url) && std::getline(in, dir)) {
    forestmap::testing::PostgresCluster::StopAndRemove(dir);
  }
  fs::remove(state);
}

bool Alive(pid_t pid) { return pid > 0 && (kill(pid, 0) == 0 || errno == EPERM); }

// STATE.<pid> files of runs that no longer exist, and STATE itself (written before state files
// were per run): their clusters are stopped.
void StopAbandoned(const std::string& state) {
  const fs::path base(state);
  const std::string prefix = base.filename().string() + ".";
  StopFromState(state);
  std::error_code error;
  for (const fs::directory_entry& entry : fs::directory_iterator(base.parent_path(), error)) {
    const std::string name = entry.path().filename().string();
    if (!name.starts_with(prefix)) continue;
    const std::string pid = name.substr(prefix.size());
    if (pid.empty() || pid.size() > 9 || pid.find_first_not_of("0123456789") != std::string::npos) {
      continue;
    }
    if (!Alive(static_cast<pid_t>(std::stoll(pid)))) StopFromState(entry.path().string());
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3 || (std::string(argv[1]) != "start" && std::string(argv[1]) != "stop")) {
    std::cerr << "usage: pg_fixture start|stop STATE_FILE\n";
    return 2;
  }
  const std::string state = forestmap::testing::RunStateFile(argv[2]);
  try {
    StopFromState(state);  // this run's (a repeated start, or its stop)
    if (std::string(argv[1]) == "stop") return 0;
    StopAbandoned(argv[2]);
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
