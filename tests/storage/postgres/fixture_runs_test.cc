// Two CTest runs at once in one build folder (a quick `ctest -R` beside a full run) each have
// their own PostgreSQL cluster (tests/pg_fixture_main.cc): the second run's start and stop leave
// the first run's cluster serving, and the cluster of a run that is gone without its stop (killed)
// is stopped by the next run's start. A run is played by a child process that runs `pg_fixture`
// as its own child, as CTest does.

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

#include "storage/map_store.h"
#include "storage/postgres/connection.h"
#include "tests/pg_fixture.h"

namespace forestmap::testing {
namespace {

namespace fs = std::filesystem;

// Runs `pg_fixture COMMAND STATE` as a child of this process; its exit status.
int RunFixture(const char* command, const std::string& state) {
  const pid_t pid = fork();
  if (pid == 0) {
    execl(PG_FIXTURE_PATH, PG_FIXTURE_PATH, command, state.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  int status = 0;
  if (pid < 0 || waitpid(pid, &status, 0) != pid) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// One CTest run: starts its cluster at construction, stops it at Finish(true) or just ends at
// Finish(false) (a run killed before its stop).
class FakeRun {
 public:
  explicit FakeRun(const std::string& state) : state_(state) {
    if (pipe(to_run_) != 0 || pipe(from_run_) != 0) throw std::runtime_error("pipe failed");
    pid_ = fork();
    if (pid_ == 0) Child();
    run_pid_ = pid_;
    close(to_run_[0]);
    close(from_run_[1]);
    char started = 1;
    if (read(from_run_[0], &started, 1) != 1) started = 1;
    started_ = started == 0;
  }
  ~FakeRun() {
    if (pid_ > 0) Finish(false);
  }
  bool started() const { return started_; }
  // Its state file, named by its pid as CTest's pid names a real run's (RunStateFile).
  std::string state_file() const { return state_ + "." + std::to_string(run_pid_); }
  // The server URL its tests use: line 1 of its state file.
  std::string url() const {
    std::ifstream in(state_file());
    std::string line;
    std::getline(in, line);
    return line;
  }
  void Finish(bool stop) {
    const char command = stop ? 's' : 'x';
    if (write(to_run_[1], &command, 1) != 1) ADD_FAILURE() << "the run is gone";
    int status = 0;
    waitpid(pid_, &status, 0);
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "pg_fixture stop failed";
    close(to_run_[1]);
    close(from_run_[0]);
    pid_ = 0;
  }

 private:
  [[noreturn]] void Child() {
    close(to_run_[1]);
    close(from_run_[0]);
    const char started = static_cast<char>(RunFixture("start", state_));
    if (write(from_run_[1], &started, 1) != 1) _exit(1);
    char command = 'x';
    if (read(to_run_[0], &command, 1) != 1) _exit(1);
    _exit(command == 's' ? RunFixture("stop", state_) : 0);
  }

  std::string state_;
  pid_t pid_ = 0;      // 0 once finished
  pid_t run_pid_ = 0;  // kept after it finished
  int to_run_[2] = {-1, -1};
  int from_run_[2] = {-1, -1};
  bool started_ = false;
};

bool Serves(const std::string& url) {
  try {
    storage::pg::Connection conn(url + "/postgres");
    return conn.Exec("SELECT 1").Int64(0, 0) == 1;
  } catch (const storage::StorageError&) {
    return false;
  }
}

class PgFixtureRunsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("pg_fixture_runs_" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    state_ = (dir_ / "pg_cluster.state").string();
  }
  // Whatever a failed test left: the clusters its state files name.
  void TearDown() override {
    for (const fs::directory_entry& entry : fs::directory_iterator(dir_)) {
      std::ifstream in(entry.path());
      std::string url, cluster_dir;
      if (std::getline(in, url) && std::getline(in, cluster_dir)) {
        PostgresCluster::StopAndRemove(cluster_dir);
      }
    }
    fs::remove_all(dir_);
  }

  fs::path dir_;
  std::string state_;
};

TEST_F(PgFixtureRunsTest, ASecondRunInTheSameFolderLeavesTheFirstRunsClusterServing) {
  FakeRun first(state_);
  ASSERT_TRUE(first.started());
  const std::string first_url = first.url();
  ASSERT_TRUE(Serves(first_url)) << first_url;
  {
    FakeRun second(state_);
    ASSERT_TRUE(second.started());
    EXPECT_NE(second.url(), first_url);
    EXPECT_TRUE(Serves(second.url()));
    EXPECT_TRUE(Serves(first_url)) << "the second run's start stopped the first run's cluster";
    second.Finish(true);
    EXPECT_FALSE(fs::exists(second.state_file()));
  }
  EXPECT_TRUE(Serves(first_url)) << "the second run's stop stopped the first run's cluster";

  first.Finish(false);  // killed before its stop: the cluster and the state file stay
  ASSERT_TRUE(fs::exists(first.state_file()));
  ASSERT_TRUE(Serves(first_url));
  FakeRun next(state_);  // the next run's start stops them
  ASSERT_TRUE(next.started());
  EXPECT_FALSE(fs::exists(first.state_file()));
  EXPECT_FALSE(Serves(first_url));
  next.Finish(true);
  EXPECT_TRUE(fs::is_empty(dir_));
}

}  // namespace
}  // namespace forestmap::testing
