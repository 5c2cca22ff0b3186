#pragma once
// The built binaries as an operator runs them, for tests: shell command lines with their output
// captured, and forestmapd started in the background until it logs "serving on". Tests that
// include this define FORESTMAPD_PATH and FORESTMAP_CLI_PATH (the built binaries).

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <thread>

namespace forestmap::test {

struct CommandResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};

inline std::string ReadFile(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// Runs a shell command line with its stdout and stderr into the files `out` and `err`.
inline CommandResult RunShell(const std::string& command, const std::filesystem::path& out,
                              const std::filesystem::path& err) {
  const int status =
      std::system((command + " >'" + out.string() + "' 2>'" + err.string() + "'").c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, ReadFile(out), ReadFile(err)};
}

// The command line of `forestmap --server ADDRESS ARGS` with FORESTMAP_TOKEN and FORESTMAP_SERVER
// unset, then `env` (shell words VAR=value) set.
inline std::string ClientCommand(const std::string& address, const std::string& args,
                                 const std::string& env = "") {
  return "env -u FORESTMAP_TOKEN -u FORESTMAP_SERVER " + env +
         " '" FORESTMAP_CLI_PATH "' --server " + address + " " + args;
}

// One forestmapd started through the shell; stopped by Stop() or at destruction.
class DaemonProcess {
 public:
  static constexpr auto kStartTimeout = std::chrono::seconds(20);

  DaemonProcess() = default;
  DaemonProcess(const DaemonProcess&) = delete;
  DaemonProcess& operator=(const DaemonProcess&) = delete;
  ~DaemonProcess() { Stop(); }

  // Starts `forestmapd ARGS` in the background (with the shell words VAR=value of `env` in its
  // environment), stderr into `log`, its pid into `pid_file`, and waits for its "serving on
  // HOST:PORT" line (address() then holds 127.0.0.1:PORT).
  ::testing::AssertionResult Start(const std::string& args, const std::filesystem::path& log,
                                   const std::filesystem::path& pid_file,
                                   const std::string& env = "") {
    const std::string command = (env.empty() ? "exec " : "exec env " + env + " ") +
                                "'" FORESTMAPD_PATH "' " + args + " 2>'" + log.string() + "'";
    const std::string background = "(" + command + ") & echo $! > '" + pid_file.string() + "'";
    if (std::system(background.c_str()) != 0) {
      return ::testing::AssertionFailure() << "cannot run " << background;
    }
    pid_ = std::stoi(ReadFile(pid_file));
    const std::regex serving(R"(serving on [^ ]*:(\d+))");
    const auto deadline = std::chrono::steady_clock::now() + kStartTimeout;
    std::smatch match;
    std::string text;
    while (std::chrono::steady_clock::now() < deadline) {
      text = ReadFile(log);
      if (std::regex_search(text, match, serving)) {
        address_ = "127.0.0.1:" + match[1].str();
        return ::testing::AssertionSuccess();
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return ::testing::AssertionFailure() << "forestmapd did not start: " << text;
  }

  // SIGTERM, then waits up to 5 s for the process to end.
  void Stop() {
    if (pid_ <= 0) return;
    kill(pid_, SIGTERM);
    for (int i = 0; i < 200 && kill(pid_, 0) == 0; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(25));
    }
    pid_ = -1;
  }

  const std::string& address() const { return address_; }
  int pid() const { return pid_; }  // -1 when stopped

 private:
  int pid_ = -1;
  std::string address_;
};

}  // namespace forestmap::test
