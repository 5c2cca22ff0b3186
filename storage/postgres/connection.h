#pragma once
// The one wrapper around libpq (PostgreSQL's C client): RAII connections and results, bound
// parameters in text form (never SQL built from values), array literals for bulk writes through
// unnest(), a RAII transaction and the schema migration. Every libpq failure
// becomes a StorageError whose code follows the SQLSTATE (unique violation -> kAlreadyExists,
// serialization failure / deadlock -> kConflict, lock timeout / lost or refused connection /
// server shutting down -> kUnavailable, disk_full -> kFull, read-only transaction -> kReadOnly,
// data or index corrupted -> kCorrupt).
//
// Numbers travel as text: doubles are written with std::to_chars (shortest form that parses back
// to the same bits) and PostgreSQL 12+ prints float8 the same way (extra_float_digits = 1), so
// values round-trip bit for bit, -0.0 included.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

struct pg_conn;
struct pg_result;

namespace forestmap::storage::pg {

// Positional parameters $1, $2, ... in the order they are added.
class Params {
 public:
  Params& Int64(int64_t value);
  Params& Double(double value);
  Params& OptionalDouble(const std::optional<double>& value);  // nullopt -> NULL
  Params& Text(std::string_view value);
  Params& OptionalText(const std::optional<std::string>& value);  // nullopt -> NULL
  Params& Bool(bool value);

  const std::vector<std::optional<std::string>>& values() const { return values_; }

 private:
  std::vector<std::optional<std::string>> values_;
};

// Text of a double that PostgreSQL parses back to the same bits (Infinity spelt its way).
std::string DoubleText(double value);

// A PostgreSQL array literal ('{1,2,NULL}') built element by element, for unnest($n::type[]).
class ArrayLiteral {
 public:
  void Int64(int64_t value);
  void Double(double value);
  void OptionalDouble(const std::optional<double>& value);
  void Text(std::string_view value);  // quoted and escaped
  void OptionalText(const std::optional<std::string>& value);
  void Null();
  std::string Finish() const { return text_ + "}"; }

 private:
  void Separator();
  std::string text_ = "{";
  bool first_ = true;
};

// A query's result; column values are read as text and converted. Rows and columns from 0.
class Result {
 public:
  explicit Result(pg_result* result);
  ~Result();
  Result(Result&& other) noexcept;
  Result& operator=(Result&&) = delete;
  Result(const Result&) = delete;
  Result& operator=(const Result&) = delete;

  int rows() const;
  int64_t affected() const;  // rows changed by INSERT / UPDATE / DELETE
  bool IsNull(int row, int column) const;
  int64_t Int64(int row, int column) const;
  double Double(int row, int column) const;
  std::optional<double> OptionalDouble(int row, int column) const;  // NULL -> nullopt
  std::string Text(int row, int column) const;                      // NULL -> ""
  bool Bool(int row, int column) const;

 private:
  const char* Value(int row, int column) const;
  pg_result* result_;
};

class Connection {
 public:
  // Connects with a libpq connection string or URI (postgresql://user@host:port/db?...).
  // Throws StorageError naming the server (the password never appears in messages).
  explicit Connection(const std::string& conninfo);
  ~Connection();
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  // One statement with bound parameters.
  Result Exec(const char* sql, const Params& params = {});
  // Several statements without parameters (schema steps).
  void ExecScript(const char* sql);
  // False once the server connection is lost: the pool then drops this connection.
  bool healthy() const;

 private:
  // Throws the StorageError of a failed result (null: lost connection or no memory).
  void Check(pg_result* raw) const;
  pg_conn* conn_ = nullptr;
};

// BEGIN ... COMMIT; rolled back in the destructor unless Commit() ran. Reads run REPEATABLE READ
// READ ONLY (one snapshot for the whole read); writes run READ COMMITTED and serialize per map
// through an advisory lock (see PostgresMapStore).
class Transaction {
 public:
  enum class Kind { kRead, kWrite };
  Transaction(Connection& conn, Kind kind);
  ~Transaction();
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;
  void Commit();

 private:
  Connection& conn_;
  bool done_ = false;
};

// Brings the schema to steps.size() (table forestmap_schema holds the version). Step i takes the
// schema from version i to i + 1; all steps run in one transaction under an advisory lock, so
// replicas starting together migrate once. A newer schema is refused before anything changes.
void MigrateSchema(Connection& conn, const std::vector<const char*>& steps);

// "host:port/db" of a connection string, for messages (no user, no password).
std::string DescribeServer(const std::string& conninfo);

}  // namespace forestmap::storage::pg
