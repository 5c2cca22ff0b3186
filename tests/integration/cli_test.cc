// Runs the built `forestmap` binary (FORESTMAP_CLI_PATH) as a user would.

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "client/io/tree_csv.h"
#include "tests/client/fake_forestmap_server.h"
#include "tests/shared_data.h"

namespace forestmap::client {
namespace {

namespace fs = std::filesystem;

struct Result {
  int exit_code = -1;
  std::string out;
  std::string err;
};

std::string ReadFile(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

class CliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("forestmap_cli_test_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Runs `forestmap ARGS` through the shell (ARGS are shell words), with FORESTMAP_SERVER unset
  // unless `env` sets it.
  Result Run(const std::string& args, const std::string& env = "") {
    const fs::path out = dir_ / "stdout", err = dir_ / "stderr";
    const std::string command = "env -u FORESTMAP_SERVER " + env + " '" FORESTMAP_CLI_PATH "' " +
                                args + " >'" + out.string() + "' 2>'" + err.string() + "'";
    const int status = std::system(command.c_str());
    Result result;
    result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    result.out = ReadFile(out);
    result.err = ReadFile(err);
    return result;
  }

  fs::path Write(const std::string& name, const std::string& content) {
    const fs::path path = dir_ / name;
    std::ofstream(path) << content;
    return path;
  }

  fs::path dir_;
};

bool StartsWith(const std::string& text, const std::string& prefix) {
  return text.rfind(prefix, 0) == 0;
}

int CountLines(const std::string& text) {
  return static_cast<int>(std::count(text.begin(), text.end(), '\n'));
}

TEST_F(CliTest, HelpExitsZeroForEveryCommand) {
  const Result top = Run("--help");
  EXPECT_EQ(top.exit_code, 0);
  EXPECT_NE(top.out.find("--server"), std::string::npos);
  EXPECT_NE(top.out.find("relocalize"), std::string::npos);
  for (const char* command :
       {"map", "map create", "map build", "map list", "map show", "map delete", "map export",
        "map history", "map restore", "map remove-source", "map changes", "relocalize", "track",
        "observe", "detect"}) {
    SCOPED_TRACE(command);
    const Result result = Run(std::string(command) + " --help");
    EXPECT_EQ(result.exit_code, 0);
    EXPECT_NE(result.out.find("Usage: forestmap " + std::string(command)), std::string::npos)
        << result.out;
  }
  EXPECT_NE(Run("relocalize --help").out.find("X,Y,YAW_DEG,RADIUS_M"), std::string::npos);
  // Benchmarks, the simulator and demo data are forestmap-lab's (tests/integration/lab_test.cc).
  for (const char* lab :
       {"simulate", "bench-reloc", "bench-mapping", "bench-server", "bench-load", "demo-data"}) {
    EXPECT_EQ(top.out.find("\n  " + std::string(lab) + " "), std::string::npos) << lab;
  }
}

TEST_F(CliTest, VersionSaysVersionCommitAndBuildType) {
  const Result version = Run("--version");
  EXPECT_EQ(version.exit_code, 0);
  // "forestmap 1.2.3 (commit abc1234, Release)\n"
  unsigned major = 0, minor = 0, patch = 0;
  char commit[64] = {}, build_type[32] = {};
  EXPECT_EQ(std::sscanf(version.out.c_str(), "forestmap %u.%u.%u (commit %63[^,], %31[A-Za-z])",
                        &major, &minor, &patch, commit, build_type),
            5)
      << version.out;
  EXPECT_EQ(version.out.substr(version.out.find(')') + 1), "\n") << version.out;
}

TEST_F(CliTest, PlotColoursByAColumnLabelsTreesAndWarnsOfAQueryThatIsNotTheAnswers) {
  const fs::path trees = Write("trees.csv",
                               "id,x,y,dbh,species\n1,0,0,0.3,oak\n2,10,0,0.4,ash\n3,0,10,0.2,oak\n"
                               "4,10,10,0.5,elm\n5,5,5,0.3,oak\n");
  const std::string picture = (dir_ / "p.png").string();
  const Result coloured = Run("plot --trees '" + trees.string() + "' --out '" + picture +
                              "' --color-by species --labels");
  EXPECT_EQ(coloured.exit_code, 0) << coloured.err;
  EXPECT_TRUE(fs::exists(picture));
  const Result unknown =
      Run("plot --trees '" + trees.string() + "' --out '" + picture + "' --color-by colour");
  EXPECT_EQ(unknown.exit_code, 1);
  EXPECT_NE(unknown.err.find("--color-by colour: no tree has that column (they have species)"),
            std::string::npos)
      << unknown.err;

  // The answer put the sensor at (5, 5) facing +x and matched 3 trees: a query of this frame lies
  // on the map; another frame's does not, and the picture says so.
  const fs::path answer =
      Write("answer.json", R"({"status":"localized","x":5,"y":5,"z":0,"yaw_deg":0,"inliers":3})"
                           "\n");
  const fs::path ours = Write("ours.csv", "x,y,z,dbh\n-5,-5,0,0.3\n5,-5,0,0.4\n-5,5,0,0.2\n");
  const fs::path other = Write("other.csv", "x,y,z,dbh\n-2,-3,0,0.3\n3,-1,0,0.4\n-1,2,0,0.2\n");
  const std::string drawn = "plot --trees '" + trees.string() + "' --out '" + picture +
                            "' --answer '" + answer.string() + "' --query ";
  const Result matching = Run(drawn + "'" + ours.string() + "'");
  EXPECT_EQ(matching.exit_code, 0) << matching.err;
  EXPECT_EQ(matching.err.find("warning"), std::string::npos) << matching.err;
  const Result mismatched = Run(drawn + "'" + other.string() + "'");
  EXPECT_EQ(mismatched.exit_code, 0) << mismatched.err;
  EXPECT_NE(mismatched.err.find("plot: warning: 0 of the 3 query trees lie on a map tree where "
                                "the answer matched 3"),
            std::string::npos)
      << mismatched.err;
}

TEST_F(CliTest, ATypoGetsTheClosestCommandOrFlag) {
  const Result command = Run("map craete x");
  EXPECT_EQ(command.exit_code, 2);
  EXPECT_NE(command.err.find("did you mean 'forestmap map create'?"), std::string::npos)
      << command.err;
  const Result flag = Run("map list --jsn");
  EXPECT_EQ(flag.exit_code, 2);
  EXPECT_NE(flag.err.find("did you mean 'forestmap map list --json'?"), std::string::npos)
      << flag.err;
  const Result global = Run("--servr x:1 map list");
  EXPECT_NE(global.err.find("did you mean 'forestmap --server'?"), std::string::npos) << global.err;
  EXPECT_EQ(Run("map frobnicate").err.find("did you mean"), std::string::npos);
}

TEST_F(CliTest, AnAddressWithoutAPortDialsForestmapdsPort) {
  // No server there: the error names the address dialled (gRPC alone would dial 443).
  const Result result = Run("--server 127.0.0.1 map list");
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_NE(result.err.find("127.0.0.1:50051"), std::string::npos) << result.err;
  EXPECT_EQ(result.err.find(":443"), std::string::npos) << result.err;
  // A host name too, and each of several replicas.
  const Result named = Run("--server localhost map list");
  EXPECT_EQ(named.exit_code, 1);
  EXPECT_NE(named.err.find("localhost:50051"), std::string::npos) << named.err;
  EXPECT_EQ(named.err.find(":443"), std::string::npos) << named.err;
  const Result replicas = Run("--server localhost,127.0.0.1:1 health --timeout 0.5");
  EXPECT_EQ(replicas.exit_code, 1);
  EXPECT_NE((replicas.out + replicas.err).find("localhost:50051"), std::string::npos)
      << replicas.out << replicas.err;
}

TEST_F(CliTest, InvalidCommandLinesExitNonZeroWithAMessage) {
  struct Case {
    const char* args;
    const char* message;
  };
  for (const Case& c : std::vector<Case>{
           {"", "a command is required"},
           {"map", "a command is required"},
           {"frobnicate", "frobnicate"},
           {"--bogus map list", "--bogus"},
           {"map create", "NAME is required"},
           {"map show", "NAME is required"},
           {"relocalize m", "--trees FILE, --scan SCAN or --frames FILE is required"},
           {"relocalize m --trees a.csv --frames b.csv", "--trees excludes --frames"},
           {"relocalize m --frames b.csv --prior 1,2,3,4", "excludes"},
           {"relocalize m --trees a.csv --prior 1,2", "--prior: expected X,Y,RADIUS_M"},
           {"relocalize m --trees a.csv --prior 1,2,x,4", "--prior: 'x' is not a number"},
           {"relocalize m --trees a.csv --prior 1,2,-5", "--prior: RADIUS_M must be > 0"},
           {"--server '' map list", "--server"},
           {"track m", "--frames is required"},
           {"map build m", "--frames is required"},
           {"relocalize m --scan /no/such/scan.pcd", "/no/such/scan.pcd"},
           {"simulate --generate 10", "simulate"},
           {"bench-reloc --map m.csv", "bench-reloc"},
       }) {
    SCOPED_TRACE(c.args);
    const Result result = Run(c.args);
    EXPECT_EQ(result.exit_code, 2);
    EXPECT_TRUE(StartsWith(result.err, "forestmap: error: ")) << result.err;
    EXPECT_NE(result.err.find(c.message), std::string::npos) << result.err;
    EXPECT_TRUE(result.out.empty());
  }
}

TEST_F(CliTest, UnreachableServerIsOneClearLineAndExitOne) {
  const Result result = Run("--server 127.0.0.1:1 map list");
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_TRUE(StartsWith(result.err, "forestmap: error: cannot reach forestmapd at 127.0.0.1:1: "))
      << result.err;
  EXPECT_NE(result.err.find("(is it running? use --server)"), std::string::npos);
  EXPECT_EQ(CountLines(result.err), 1) << result.err;

  // FORESTMAP_SERVER replaces the default; --server wins over both.
  EXPECT_NE(Run("map list", "FORESTMAP_SERVER=127.0.0.1:2").err.find("at 127.0.0.1:2:"),
            std::string::npos);
  EXPECT_NE(Run("--server 127.0.0.1:3 map list", "FORESTMAP_SERVER=127.0.0.1:2")
                .err.find("at 127.0.0.1:3:"),
            std::string::npos);
}

TEST_F(CliTest, BadFilesFailBeforeContactingTheServer) {
  const fs::path bad = Write("bad.csv", "x,y\n1,2\nabc,3\n");
  // The server address is unreachable: the file error must come first.
  const Result create = Run("--server 127.0.0.1:1 map create m --trees '" + bad.string() + "'");
  EXPECT_EQ(create.exit_code, 1);
  EXPECT_EQ(create.err,
            "forestmap: error: " + bad.string() + ":3: column 'x': 'abc' is not a number\n");
  const Result missing = Run("--server 127.0.0.1:1 relocalize m --trees /no/such/file.csv");
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_EQ(missing.err,
            "forestmap: error: /no/such/file.csv: cannot open: No such file or directory\n");
  const Result empty = Run("--server 127.0.0.1:1 relocalize m --trees '" +
                           Write("empty.csv", "x,y\n").string() + "'");
  EXPECT_EQ(empty.exit_code, 1);
  EXPECT_NE(empty.err.find("no trees (header only)"), std::string::npos);
}

// ---- Against an in-process fake server ----

std::string Scan(int trees) {
  std::string csv = "x,y,z,dbh,axis_x,axis_y,axis_z,score\n";
  for (int i = 0; i < trees; ++i) {
    csv += std::to_string(i) + "," + std::to_string(2 * i) + ",-1.5,0.3,0,0,1,0.8\n";
  }
  return csv;
}

TEST_F(CliTest, MapCreateListShowExportDelete) {
  testing::FakeForestMapServer server;
  const std::string s = "--server " + server.address() + " ";
  const fs::path trees =
      Write("trees.csv", "tree_id,x_m,y_m,dbh_m,species\n1,0.5,1,0.2,pine\n2,10,-4,,oak\n");
  const Result create = Run(s +
                            "map create plot --crs EPSG:2959 --description 'test plot' "
                            "--trees '" +
                            trees.string() + "'");
  EXPECT_EQ(create.exit_code, 0) << create.err;
  EXPECT_EQ(create.out, "created map 'plot' (2 trees, version 2)\n");
  EXPECT_EQ(Run(s + "map create empty").exit_code, 0);

  const Result list = Run(s + "map list");
  EXPECT_EQ(list.exit_code, 0);
  EXPECT_EQ(list.out,
            "NAME   TREES  VERSION  CRS        EXTENT\n"
            "empty  0      1        -          -\n"
            "plot   2      2        EPSG:2959  x 0.50..10.00 m, y -4.00..1.00 m\n");

  const Result show = Run(s + "map show plot");
  EXPECT_EQ(show.exit_code, 0);
  EXPECT_NE(show.out.find("description: test plot\n"), std::string::npos) << show.out;

  const Result to_stdout = Run(s + "map export plot");
  EXPECT_EQ(to_stdout.exit_code, 0);
  EXPECT_EQ(to_stdout.out, "id,x,y,z,dbh,species\n1,0.5,1,,0.2,pine\n2,10,-4,,,oak\n");
  const fs::path exported = dir_ / "exported.csv";
  const Result to_file = Run(s + "map export plot --out '" + exported.string() + "'");
  EXPECT_EQ(to_file.exit_code, 0);
  EXPECT_EQ(ReadMapTreesCsv(exported.string()), ReadMapTreesCsv(trees.string()));

  const Result duplicate = Run(s + "map create plot");
  EXPECT_EQ(duplicate.exit_code, 1);
  EXPECT_TRUE(StartsWith(duplicate.err, "forestmap: error: CreateMap: ALREADY_EXISTS: "));

  // Deleting drops the whole history: never without a word. No terminal and no --yes: refused.
  const Result unconfirmed = Run(s + "map delete plot </dev/null");
  EXPECT_EQ(unconfirmed.exit_code, 1);
  EXPECT_NE(unconfirmed.err.find("refusing to delete map 'plot' (2 trees"), std::string::npos)
      << unconfirmed.err;
  EXPECT_EQ(Run(s + "map show plot").exit_code, 0);
  // On a terminal (a pseudo-terminal made by script(1)) it asks for the map's name.
  const auto typed = [&](const std::string& answer) {
    const std::string command = "printf '" + answer +
                                "\\n' | env -u FORESTMAP_SERVER script -qec \"'" FORESTMAP_CLI_PATH
                                "' " +
                                s + "map delete plot\" /dev/null >/dev/null 2>&1";
    const int status = std::system(command.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  };
  EXPECT_EQ(typed("plo"), 1);
  EXPECT_EQ(Run(s + "map show plot").exit_code, 0);
  EXPECT_EQ(typed("plot"), 0);
  const Result gone = Run(s + "map show plot");
  EXPECT_EQ(gone.exit_code, 1);
  EXPECT_EQ(gone.err, "forestmap: error: GetMap: NOT_FOUND: no map named 'plot'\n");
}

TEST_F(CliTest, FailedCreateWithTreesLeavesNoMap) {
  testing::FakeForestMapServer server;
  server.service().fail_uploads = true;
  const fs::path trees = Write("trees.csv", "x,y\n1,2\n3,4\n");
  const Result result =
      Run("--server " + server.address() + " map create m --trees '" + trees.string() + "'");
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_NE(result.err.find("INTERNAL: disk full"), std::string::npos) << result.err;
  EXPECT_NE(result.err.find("no map was created"), std::string::npos) << result.err;
  EXPECT_TRUE(server.service().maps.empty());
  // One upload stream that creates the map: no CreateMap call that could leave a map behind.
  ASSERT_FALSE(server.service().upload_messages.empty());
  EXPECT_TRUE(server.service().upload_messages[0].header().create_map());
}

TEST_F(CliTest, RelocalizePrintsOneJsonLine) {
  testing::FakeForestMapServer server;
  const std::string s = "--server " + server.address() + " ";
  ASSERT_EQ(Run(s + "map create m").exit_code, 0);
  const fs::path scan = Write("scan.csv", Scan(12));

  const Result plain = Run(s + "relocalize m --trees '" + scan.string() + "'");
  EXPECT_EQ(plain.exit_code, 0) << plain.err;
  ASSERT_EQ(CountLines(plain.out), 1) << plain.out;
  const auto line = nlohmann::json::parse(plain.out);
  EXPECT_FALSE(line.contains("frame"));
  EXPECT_EQ(line["status"], "localized");
  EXPECT_EQ(line["x"], 10.0);
  EXPECT_EQ(line["y"], 20.0);
  EXPECT_NEAR(line["yaw_deg"].get<double>(), 30.0, 1e-9);
  EXPECT_EQ(line["inliers"], 12);
  EXPECT_EQ(line["server_ms"], 2.5);

  // The fake answers at the prior position: the flag's numbers arrive as x, y and radius.
  const Result prior = Run(s + "relocalize m --trees '" + scan.string() + "' --prior 5,6,12");
  EXPECT_EQ(prior.exit_code, 0) << prior.err;
  const auto at_prior = nlohmann::json::parse(prior.out);
  EXPECT_EQ(at_prior["x"], 5.0);
  EXPECT_EQ(at_prior["y"], 6.0);
  EXPECT_EQ(server.service().last_relocalize.prior().radius_m(), 12.0);

  // not_found is an answer, not a failure: exit 0, no pose.
  const Result few = Run(s + "relocalize m --trees '" + Write("few.csv", Scan(5)).string() + "'");
  EXPECT_EQ(few.exit_code, 0);
  const auto not_found = nlohmann::json::parse(few.out);
  EXPECT_EQ(not_found["status"], "not_found");
  EXPECT_FALSE(not_found.contains("x"));

  const Result no_map = Run(s + "relocalize nope --trees '" + scan.string() + "'");
  EXPECT_EQ(no_map.exit_code, 1);
  EXPECT_EQ(no_map.err, "forestmap: error: Relocalize: NOT_FOUND: no map named 'nope'\n");
}

TEST_F(CliTest, RelocalizeOverASetOfMapsSendsTheSetAndPrintsTheMapFoundIn) {
  testing::FakeForestMapServer server;
  const std::string s = "--server " + server.address() + " ";
  ASSERT_EQ(Run(s + "map create plot-a").exit_code, 0);
  ASSERT_EQ(Run(s + "map create plot-b").exit_code, 0);
  const std::string trees = " --trees '" + Write("scan.csv", Scan(12)).string() + "'";

  const Result listed = Run(s + "relocalize --maps plot-a,plot-b" + trees);
  ASSERT_EQ(listed.exit_code, 0) << listed.err;
  EXPECT_EQ(nlohmann::json::parse(listed.out)["map"], "plot-b");  // the fake's choice
  const v1::RelocalizeRequest& sent = server.service().last_relocalize;
  EXPECT_TRUE(sent.name().empty());
  EXPECT_EQ(std::vector<std::string>(sent.maps().names().begin(), sent.maps().names().end()),
            (std::vector<std::string>{"plot-a", "plot-b"}));

  ASSERT_EQ(Run(s + "relocalize --maps-matching 'plot-*'" + trees).exit_code, 0);
  EXPECT_EQ(server.service().last_relocalize.maps().name_pattern(), "plot-*");
  EXPECT_EQ(server.service().last_relocalize.maps().names_size(), 0);
  const Result all = Run(s + "relocalize --all-maps" + trees);
  ASSERT_EQ(all.exit_code, 0) << all.err;
  EXPECT_TRUE(server.service().last_relocalize.maps().all_readable());
  EXPECT_EQ(nlohmann::json::parse(all.out)["map"], "plot-a");

  const Result one = Run(s + "relocalize plot-a" + trees);  // one map: no set, its name printed
  EXPECT_FALSE(server.service().last_relocalize.has_maps());
  EXPECT_EQ(nlohmann::json::parse(one.out)["map"], "plot-a");

  for (const auto& [bad, says] : std::vector<std::pair<std::string, std::string>>{
           {"relocalize" + trees, "NAME, --maps, --maps-matching or --all-maps is required"},
           {"relocalize plot-a --maps plot-b" + trees, "excludes"},
           {"relocalize --all-maps --maps-matching 'p*'" + trees, "excludes"}}) {
    const Result refused = Run(s + bad);
    EXPECT_EQ(refused.exit_code, 2) << bad << ": " << refused.err;
    EXPECT_NE(refused.err.find(says), std::string::npos) << bad << ": " << refused.err;
  }
}

// Mapping an unknown forest: 100 real Wild_V01 frames, no poses, become a new map.
TEST_F(CliTest, MapBuildCreatesAMapFromFramesAlone) {
  const std::string frames = std::string(FORESTMAP_SHARED_DATA) + "/sequences/Wild_V01/trees.csv";
  if (!fs::exists(frames)) FORESTMAP_SKIP_WITHOUT_DATA() << "missing " << frames;
  std::ifstream in(frames);
  std::string csv, line;
  while (std::getline(in, line) && (csv.empty() || std::stoi(line) < 100)) csv += line + "\n";
  testing::FakeForestMapServer server;
  const std::string s = "--server " + server.address() + " ";
  const fs::path poses = dir_ / "built_poses.csv";
  const Result built = Run(s + "map build forest --frames '" + Write("f.csv", csv).string() +
                           "' --poses-out '" + poses.string() + "'");
  ASSERT_EQ(built.exit_code, 0) << built.err;
  EXPECT_NE(built.err.find("map build: 100/100 frames"), std::string::npos) << built.err;
  EXPECT_TRUE(StartsWith(built.out, "created map 'forest' (")) << built.out;
  const auto& uploaded = server.service().maps.at("forest").trees;
  EXPECT_GT(uploaded.size(), 500u);
  EXPECT_EQ(CountLines(ReadFile(poses)), 101);
  // The first frame defines the map frame.
  EXPECT_LT(ReadPosesCsv(poses.string()).at(0).translation().norm(), 1e-9);

  const Result again = Run(s + "map build forest --frames '" + (dir_ / "f.csv").string() + "'");
  EXPECT_EQ(again.exit_code, 1);
  EXPECT_NE(again.err.find("map 'forest' already exists"), std::string::npos) << again.err;
}

TEST_F(CliTest, RelocalizeFramesPrintsALinePerFrameAndASummary) {
  testing::FakeForestMapServer server;
  const std::string s = "--server " + server.address() + " ";
  ASSERT_EQ(Run(s + "map create m").exit_code, 0);
  std::string csv = "frame,x,y\n";
  const int frames = 120;
  for (int frame = 0; frame < frames; ++frame) {
    const int trees = frame % 2 ? 12 : 5;  // odd frames localize, even ones are not found
    for (int i = 0; i < trees; ++i)
      csv += std::to_string(frame * 10) + "," + std::to_string(i) + ",1\n";
  }
  const Result result =
      Run(s + "relocalize m --frames '" + Write("frames.csv", csv).string() + "'");
  EXPECT_EQ(result.exit_code, 0) << result.err;
  std::istringstream lines(result.out);
  std::string text;
  int count = 0;
  while (std::getline(lines, text)) {
    const auto line = nlohmann::json::parse(text);
    EXPECT_EQ(line["frame"], count * 10);
    EXPECT_EQ(line["status"], count % 2 ? "localized" : "not_found");
    ++count;
  }
  EXPECT_EQ(count, frames);
  EXPECT_NE(result.err.find("relocalize: 50/120 frames"), std::string::npos) << result.err;
  EXPECT_NE(result.err.find("relocalize: 120 frames: 60 localized, 0 ambiguous, 60 not_found; "
                            "median server time 2.5 ms"),
            std::string::npos)
      << result.err;

  // A frame with fewer than 3 trees (a clearing) is answered NOT_FOUND with its reason; the run
  // exits 0.
  const Result few = Run(s + "relocalize m --frames '" +
                         Write("few.csv", "frame,x,y\n1,0,0\n" + csv.substr(10)).string() + "'");
  EXPECT_EQ(few.exit_code, 0) << few.err;
  EXPECT_EQ(CountLines(few.out), frames + 1);
  const auto first = nlohmann::json::parse(few.out.substr(0, few.out.find('\n')));
  EXPECT_EQ(first["frame"], 1);
  EXPECT_EQ(first["status"], "not_found");
  EXPECT_EQ(first["reason"], "too_few_trees");
}

}  // namespace
}  // namespace forestmap::client
