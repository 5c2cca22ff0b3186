#pragma once
// Pieces of the PostgreSQL backend shared by the files of storage/postgres/: the backend and its
// session (storage/store_backend.h), the schema, and the row views of storage/rows.h. Not a
// public API.

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "storage/connection_pool.h"
#include "storage/postgres/connection.h"
#include "storage/postgres/store.h"
#include "storage/rows.h"
#include "storage/store_backend.h"

namespace forestmap::storage::pg {

const std::vector<const char*>& SchemaSteps();

// A row of a result as storage/rows.h reads it.
class Row {
 public:
  Row(const Result& result, int row) : result_(result), row_(row) {}
  bool IsNull(int c) const { return result_.IsNull(row_, c); }
  int64_t Int64(int c) const { return result_.Int64(row_, c); }
  double Double(int c) const { return result_.Double(row_, c); }
  std::optional<double> OptionalDouble(int c) const { return result_.OptionalDouble(row_, c); }
  std::string Text(int c) const { return result_.Text(row_, c); }
  bool Bool(int c) const { return result_.Bool(row_, c); }

 private:
  const Result& result_;
  int row_;
};

// Every row of `result` read by `read` (a storage/rows.h reader).
template <typename Read>
auto ReadAll(const Result& result, const Read& read) {
  std::vector<decltype(read(Row(result, 0)))> rows;
  rows.reserve(static_cast<size_t>(result.rows()));
  for (int r = 0; r < result.rows(); ++r) rows.push_back(read(Row(result, r)));
  return rows;
}

// Columns of rows to insert through INSERT ... SELECT FROM unnest($n::type[], ...): one array
// literal per column, filled row by row with the values storage/rows.h writes.
class ColumnArrays {
 public:
  explicit ColumnArrays(size_t columns) : columns_(columns) {}
  void Int64(int64_t v) { columns_[next_++].Int64(v); }
  void OptionalInt64(const std::optional<int64_t>& v) {
    v ? columns_[next_++].Int64(*v) : columns_[next_++].Null();
  }
  void Double(double v) { columns_[next_++].Double(v); }
  void OptionalDouble(const std::optional<double>& v) { columns_[next_++].OptionalDouble(v); }
  void Text(std::string_view v) { columns_[next_++].Text(v); }
  void OptionalText(const std::optional<std::string>& v) { columns_[next_++].OptionalText(v); }
  void Bool(bool v) { columns_[next_++].Text(v ? "t" : "f"); }
  void EndRow() { next_ = 0; }
  // The arrays as text parameters, in column order.
  void AppendTo(Params& params) const {
    for (const ArrayLiteral& column : columns_) params.Text(column.Finish());
  }

 private:
  std::vector<ArrayLiteral> columns_;
  size_t next_ = 0;
};

std::string Int64Array(std::span<const int64_t> values);

// The map's largest current tree id.
std::optional<int64_t> MaxCurrentTreeId(Connection& conn, int64_t map_id);

// Connections from a pool; reads and writes alike borrow one.
class Backend final : public StoreBackend {
 public:
  Backend(const std::string& conninfo, const PostgresMapStoreOptions& options);
  void WithReader(const Body& body) override;
  void WithWriter(const Body& body) override;
  std::unique_ptr<TreeUpload> BeginUpload(const std::string& name, const UploadPlan& plan) override;

 private:
  std::string conninfo_;  // for the uploads' own sessions
  ConnectionPool<Connection> pool_;
};

// The StoreSession of a connection (session.cc, trees.cc).
class Session final : public StoreSession {
 public:
  explicit Session(Connection& conn) : conn_(conn) {}

  void Begin(TransactionKind kind) override;
  void Commit() override;
  void Rollback() noexcept override;

  std::vector<MapInfo> ListMaps() override;
  std::optional<MapRow> FindMap(const std::string& name) override;
  bool LockMap(int64_t map_id) override;
  int64_t InsertMap(const MapInfo& info) override;
  void DeleteMap(const MapRow& map) override;
  void UpdateMap(const MapRow& map) override;
  std::optional<Extent> ScanExtent(int64_t map_id) override;

  void InsertVersion(int64_t map_id, const VersionRecord& record) override;
  std::optional<VersionRecord> FindVersion(int64_t map_id, int64_t version) override;
  std::optional<int64_t> OldestVersion(int64_t map_id) override;
  std::vector<int64_t> NewestVersions(int64_t map_id, int64_t limit) override;
  PrunedRows PruneBefore(int64_t map_id, int64_t first_kept) override;

  std::string BoundaryAt(int64_t map_id, int64_t version) override;
  void InsertBoundary(int64_t map_id, int64_t version, const std::string& encoded) override;
  std::string ColumnsAt(int64_t map_id, int64_t version) override;
  void InsertColumns(int64_t map_id, int64_t version, const std::string& encoded) override;
  void InsertRemovals(int64_t map_id, int64_t version,
                      const std::vector<TreeRemoval>& removals) override;
  std::vector<TreeRemoval> RemovalsAfter(int64_t map_id, int64_t after_version) override;

  std::vector<TreeRecord> CurrentTrees(const MapRow& map) override;
  std::vector<TreeRecord> TreesAtVersion(const MapRow& map, int64_t version) override;
  std::vector<TreeRecord> TreesInBox(const MapRow& map, const Extent& box) override;
  std::vector<TreeRecord> TreesById(const MapRow& map, std::span<const int64_t> ids) override;
  std::vector<TreeRecord> CurrentPage(const MapRow& map, const TreePageQuery& query) override;
  std::vector<TreeRecord> ClosedPage(const MapRow& map, const TreePageQuery& query) override;
  std::optional<int64_t> MaxCurrentTreeId(int64_t map_id) override;
  std::optional<int64_t> MaxTreeIdEver(int64_t map_id) override;
  void InsertTrees(const MapRow& map, const std::vector<TreeRecord>& trees,
                   const std::vector<int64_t>& ids, int64_t valid_from) override;
  std::vector<ClosedTree> CloseTrees(int64_t map_id, std::span<const int64_t> ids,
                                     int64_t version) override;
  int64_t CloseAllRows(int64_t map_id, int64_t version) override;
  std::vector<TreeRecord> ClosedTreesAt(const MapRow& map, int64_t version) override;
  std::vector<int64_t> CloseTreesAddedAfter(int64_t map_id, int64_t version, int64_t at) override;

  std::vector<ObservationRecord> ObservationsOfTrees(int64_t map_id,
                                                     std::span<const int64_t> ids) override;
  std::vector<ObservationRecord> ObservationsInCells(
      int64_t map_id, std::span<const ObservationCell> cells) override;
  std::vector<ObservationRecord> FoldedObservationsOfTrees(int64_t map_id,
                                                           std::span<const int64_t> ids) override;
  std::vector<ObservationRecord> ObservationsOfSource(int64_t map_id,
                                                      const std::string& source) override;
  std::vector<ObservationRecord> ObservationsOfSourceIn(int64_t map_id, const std::string& source,
                                                        ObservationCell lo,
                                                        ObservationCell hi) override;
  void InsertObservations(int64_t map_id, const std::vector<ObservationRecord>& rows,
                          int64_t valid_from) override;
  std::vector<int64_t> CloseObservations(int64_t map_id, std::span<const int64_t> ids,
                                         int64_t version) override;
  std::vector<ObservationRecord> ClosedObservationsAt(int64_t map_id, int64_t version) override;
  int64_t CloseObservationsAddedAfter(int64_t map_id, int64_t version, int64_t at) override;

  void ExpireRequests(int64_t before_unix_ms) override;
  bool InsertRequest(const std::string& id, const StoredRequest& answer) override;
  std::optional<StoredRequest> FindRequest(const std::string& id) override;

 private:
  Connection& conn_;
  std::optional<Transaction> transaction_;
};

}  // namespace forestmap::storage::pg
