// Issue 15 on PostgreSQL: a full disk (SQLSTATE 53100, disk_full) is a kFull StorageError, which
// the server answers RESOURCE_EXHAUSTED "database full ..." (server/status.cc), for direct writes
// and for staged uploads alike; nothing of the failed write is kept and reads go on, a store opens
// on the full disk, and a delete and a prune succeed on it (they used to fail storing their
// request ids' answers). The fault
// is real: the test database's tables live in a tablespace on a 3 MiB tmpfs that the writes
// fill, so PostgreSQL itself gets ENOSPC extending a table file (its WAL stays on the big disk).
// Mounting a tmpfs needs root (CI runs the tests as root; the cluster then runs as `nobody`) with
// CAP_SYS_ADMIN; without them the test is skipped, saying so.

#include <grpcpp/support/status.h>
#include <gtest/gtest.h>
#include <sys/mount.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "server/grpc/status.h"
#include "storage/postgres/connection.h"
#include "storage/postgres/store.h"
#include "storage/staged_writes.h"
#include "storage/write_request.h"
#include "tests/pg_fixture.h"

namespace forestmap::storage {
namespace {

namespace fs = std::filesystem;
using Code = StorageError::Code;

constexpr const char* kTinySize = "size=3m";  // of the tmpfs holding the tablespace
constexpr int kTreesPerWrite = 2000;

std::vector<TreeRecord> Trees(int64_t first_id, int count) {
  std::vector<TreeRecord> trees(static_cast<size_t>(count));
  for (int i = 0; i < count; ++i) {
    TreeRecord& tree = trees[static_cast<size_t>(i)];
    tree.id = first_id + i;
    tree.x = static_cast<double>(i % 300);
    tree.y = static_cast<double>(i / 300);
    tree.dbh = 0.3;
    tree.attributes = {{"species", "Picea abies, measured with a caliper at breast height"}};
  }
  return trees;
}

// A tablespace on a small tmpfs owned by the PostgreSQL server's user; Use() makes it the
// default tablespace of a database (for the tables a store creates there). Declare it before
// the database: the database must be gone before the tablespace is dropped and unmounted.
class TinyTablespace {
 public:
  TinyTablespace() {
    std::string pattern = (fs::temp_directory_path() / "forestmap-pg-full-XXXXXX").string();
    if (mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
    dir_ = pattern;
    if (mount("tmpfs", dir_.c_str(), "tmpfs", 0, kTinySize) != 0) {
      mount_errno_ = errno;
      error_ = std::string("mount tmpfs: ") + std::strerror(errno);
      return;
    }
    mounted_ = true;
    pg::Connection admin(testing::TestServerUrl() + "/postgres");
    struct stat data {};
    const std::string data_dir = admin.Exec("SHOW data_directory").Text(0, 0);
    if (stat(data_dir.c_str(), &data) != 0 || chown(dir_.c_str(), data.st_uid, data.st_gid) != 0 ||
        chmod(dir_.c_str(), 0700) != 0) {
      error_ = "cannot hand " + dir_ + " to the owner of " + data_dir;
      return;
    }
    name_ = "fm_full_" + std::to_string(getpid());
    // Identifiers cannot be bound: this one is made of letters and digits.
    admin.ExecScript(("CREATE TABLESPACE " + name_ + " LOCATION '" + dir_ + "'").c_str());
  }
  ~TinyTablespace() {
    try {
      if (!name_.empty()) {
        pg::Connection admin(testing::TestServerUrl() + "/postgres");
        admin.ExecScript(("DROP TABLESPACE IF EXISTS " + name_).c_str());
      }
    } catch (...) {  // the cluster goes away at the end anyway
    }
    if (mounted_) umount2(dir_.c_str(), MNT_DETACH);
    std::error_code ignored;
    fs::remove(dir_, ignored);
  }
  void Use(const std::string& database_url) const {
    pg::Connection conn(database_url);
    const std::string database = conn.Exec("SELECT current_database()").Text(0, 0);
    conn.ExecScript(("ALTER DATABASE " + database + " SET default_tablespace = " + name_).c_str());
  }
  const std::string& error() const { return error_; }
  bool may_not_mount() const { return mount_errno_ == EPERM; }

 private:
  std::string dir_, name_, error_;
  bool mounted_ = false;
  int mount_errno_ = 0;
};

// The status the server answers for the exception being handled.
grpc::Status StatusOfCurrent() { return server::StatusFromCurrentException("UploadTrees"); }

TEST(PostgresDiskFull, AFullDiskIsResourceExhaustedAndKeepsThePreviousVersion) {
  if (geteuid() != 0) GTEST_SKIP() << "needs root to mount a tmpfs (CI runs tests as root)";
  TinyTablespace tiny;
  if (tiny.may_not_mount()) GTEST_SKIP() << tiny.error() << " (a container without CAP_SYS_ADMIN)";
  ASSERT_EQ(tiny.error(), "");
  {
    testing::TestDatabase database;
    tiny.Use(database.url());
    PostgresMapStore store(database.url());
    store.CreateMap("plot", "", "");
    int64_t written = 0;
    bool full = false;
    for (int attempt = 0; attempt < 1000 && !full; ++attempt) {
      try {
        store.WriteTrees("plot", Trees(written + 1, kTreesPerWrite), WriteMode::kAppend);
        written += kTreesPerWrite;
      } catch (const StorageError& e) {
        ASSERT_EQ(e.code(), Code::kFull) << e.what();
        EXPECT_NE(std::string(e.what()).find("No space left on device"), std::string::npos)
            << e.what();
        const grpc::Status status = StatusOfCurrent();
        EXPECT_EQ(status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
        EXPECT_NE(status.error_message().find("database full"), std::string::npos);
        full = true;
      }
    }
    ASSERT_TRUE(full) << "3 MiB took " << written << " trees";
    ASSERT_GT(written, 0);  // the schema and a first write fit: the fault came from the trees
    const MapInfo info = store.GetMap("plot");  // reads go on, the failed write left nothing
    EXPECT_EQ(info.tree_count, written);
    EXPECT_EQ(info.version, 1 + written / kTreesPerWrite);
    EXPECT_EQ(static_cast<int64_t>(store.ReadMap("plot").trees.size()), written);

    // A staged upload (TEMP table on the big disk) fails at its commit, the same way.
    UploadPlan create;
    create.create_map = true;
    auto upload = store.BeginUpload("second", create);
    upload->Append(Trees(1, kTreesPerWrite));
    try {
      upload->Commit();
      ADD_FAILURE() << "a full tablespace took an upload";
    } catch (const StorageError& e) {
      EXPECT_EQ(e.code(), Code::kFull) << e.what();
      EXPECT_EQ(StatusOfCurrent().error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    }
    EXPECT_THROW(store.GetMap("second"), StorageError);  // no half-created map
    EXPECT_EQ(store.GetMap("plot").tree_count, written);
    // A server started on the full disk opens its store (the schema is current: nothing to
    // write) and serves reads.
    EXPECT_EQ(PostgresMapStore(database.url()).GetMap("plot").tree_count, written);

    // The full disk can be freed: a prune and a delete, with request ids as the server sends
    // them, succeed on the full tablespace (their answers, which need room, are not stored).
    // PostgreSQL reuses the deleted rows' room after VACUUM (autovacuum), which itself needs a
    // few pages for the tables' visibility maps: this tablespace has none left.
    const auto with_request_id = [](const std::string& id, const std::function<void()>& write) {
      WriteRequest request;
      request.id = id;
      request.rpc = "Write";
      request.encode = [](const MapInfo& map) { return map.name + std::string(64, 'x'); };
      const WriteRequestScope scope(request);
      write();
    };
    with_request_id("prune-on-full", [&] {
      EXPECT_EQ(store.PruneVersions("plot", 1).versions_removed, written / kTreesPerWrite);
    });
    with_request_id("delete-on-full", [&] { store.DeleteMap("plot"); });
    EXPECT_THROW(store.GetMap("plot"), StorageError);
    EXPECT_EQ(store.FindRequest("delete-on-full"), std::nullopt);
    EXPECT_EQ(store.ListMaps().size(), 0u);
  }  // the database is dropped, then the tablespace and the tmpfs
}

}  // namespace
}  // namespace forestmap::storage
