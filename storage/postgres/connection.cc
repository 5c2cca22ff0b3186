#include "storage/postgres/connection.h"

#include <libpq-fe.h>

#include <charconv>
#include <cmath>
#include <cstring>
#include <string>
#include <utility>

#include "storage/map_store.h"

namespace forestmap::storage::pg {
namespace {

using Code = StorageError::Code;

// SQLSTATE classes and codes that callers act on (PostgreSQL manual, appendix A).
Code CodeOfSqlState(const std::string& state) {
  if (state == "23505") return Code::kAlreadyExists;  // unique_violation
  if (state == "40001" || state == "40P01") {
    return Code::kConflict;  // serialization_failure, deadlock_detected: retry the transaction
  }
  if (state == "53100") return Code::kFull;      // disk_full (ENOSPC on the server)
  if (state == "25006") return Code::kReadOnly;  // read_only_sql_transaction (standby, setting)
  if (state == "XX001" || state == "XX002") return Code::kCorrupt;  // data / index corrupted
  // lock_not_available, too_many_connections, connection exceptions, server shutting down
  if (state == "55P03" || state == "53300" || state.rfind("08", 0) == 0 ||
      state.rfind("57P", 0) == 0) {
    return Code::kUnavailable;
  }
  if (state.rfind("22", 0) == 0 || state.rfind("23", 0) == 0) return Code::kInvalidArgument;
  return Code::kInternal;
}

std::string FirstLine(const char* message) {
  std::string text = message != nullptr ? message : "";
  const size_t end = text.find('\n');
  return end == std::string::npos ? text : text.substr(0, end);
}

}  // namespace

// ---- Parameters and literals ----

std::string DoubleText(double value) {
  if (std::isinf(value)) return value > 0 ? "Infinity" : "-Infinity";
  if (std::isnan(value)) return "NaN";
  char buffer[32];
  const auto [end, error] = std::to_chars(buffer, buffer + sizeof buffer, value);
  (void)error;  // 32 characters hold every double's shortest form
  return std::string(buffer, end);
}

Params& Params::Int64(int64_t value) {
  values_.emplace_back(std::to_string(value));
  return *this;
}
Params& Params::Double(double value) {
  values_.emplace_back(DoubleText(value));
  return *this;
}
Params& Params::OptionalDouble(const std::optional<double>& value) {
  if (value) return Double(*value);
  values_.emplace_back(std::nullopt);
  return *this;
}
Params& Params::Text(std::string_view value) {
  values_.emplace_back(std::string(value));
  return *this;
}
Params& Params::OptionalText(const std::optional<std::string>& value) {
  values_.emplace_back(value);
  return *this;
}
Params& Params::Bool(bool value) {
  values_.emplace_back(value ? "t" : "f");
  return *this;
}

void ArrayLiteral::Separator() {
  if (!first_) text_ += ',';
  first_ = false;
}
void ArrayLiteral::Int64(int64_t value) {
  Separator();
  text_ += std::to_string(value);
}
void ArrayLiteral::Double(double value) {
  Separator();
  text_ += DoubleText(value);
}
void ArrayLiteral::OptionalDouble(const std::optional<double>& value) {
  value ? Double(*value) : Null();
}
void ArrayLiteral::Text(std::string_view value) {
  Separator();
  text_ += '"';
  for (const char c : value) {
    if (c == '"' || c == '\\') text_ += '\\';
    text_ += c;
  }
  text_ += '"';
}
void ArrayLiteral::OptionalText(const std::optional<std::string>& value) {
  value ? Text(*value) : Null();
}
void ArrayLiteral::Null() {
  Separator();
  text_ += "NULL";
}

// ---- Results ----

Result::Result(pg_result* result) : result_(result) {}
Result::~Result() {
  if (result_ != nullptr) PQclear(result_);
}
Result::Result(Result&& other) noexcept : result_(std::exchange(other.result_, nullptr)) {}

int Result::rows() const { return PQntuples(result_); }
int64_t Result::affected() const {
  const char* count = PQcmdTuples(result_);
  return count[0] == '\0' ? 0 : std::stoll(count);
}
bool Result::IsNull(int row, int column) const { return PQgetisnull(result_, row, column) != 0; }
const char* Result::Value(int row, int column) const { return PQgetvalue(result_, row, column); }

int64_t Result::Int64(int row, int column) const {
  const char* text = Value(row, column);
  int64_t value = 0;
  const auto [end, error] = std::from_chars(text, text + std::strlen(text), value);
  if (error != std::errc() || *end != '\0') {
    throw StorageError(Code::kInternal, std::string("postgresql: not an integer: '") + text + "'");
  }
  return value;
}

double Result::Double(int row, int column) const {
  const char* text = Value(row, column);
  if (std::strcmp(text, "Infinity") == 0) return HUGE_VAL;
  if (std::strcmp(text, "-Infinity") == 0) return -HUGE_VAL;
  double value = 0;
  const auto [end, error] = std::from_chars(text, text + std::strlen(text), value);
  if (error != std::errc() || *end != '\0') {
    throw StorageError(Code::kInternal, std::string("postgresql: not a number: '") + text + "'");
  }
  return value;
}

std::optional<double> Result::OptionalDouble(int row, int column) const {
  if (IsNull(row, column)) return std::nullopt;
  return Double(row, column);
}
std::string Result::Text(int row, int column) const { return Value(row, column); }
bool Result::Bool(int row, int column) const { return Value(row, column)[0] == 't'; }

// ---- Connections ----

Connection::Connection(const std::string& conninfo) {
  conn_ = PQconnectdb(conninfo.c_str());
  if (conn_ == nullptr || PQstatus(conn_) != CONNECTION_OK) {
    const std::string why = conn_ != nullptr ? FirstLine(PQerrorMessage(conn_)) : "out of memory";
    if (conn_ != nullptr) PQfinish(conn_);
    conn_ = nullptr;
    throw StorageError(Code::kUnavailable,
                       "postgresql: cannot connect to " + DescribeServer(conninfo) + ": " + why);
  }
  // Messages in English and UTC timestamps whatever the server's defaults; a server-side notice
  // (e.g. "relation already exists, skipping") must not reach stderr.
  PQsetNoticeProcessor(
      conn_, [](void*, const char*) {}, nullptr);
  ExecScript("SET client_encoding = 'UTF8'; SET lc_messages = 'C'; SET TIME ZONE 'UTC'");
}

Connection::~Connection() {
  if (conn_ != nullptr) PQfinish(conn_);
}

bool Connection::healthy() const { return PQstatus(conn_) == CONNECTION_OK; }

Result Connection::Exec(const char* sql, const Params& params) {
  const auto& values = params.values();
  std::vector<const char*> pointers(values.size());
  for (size_t i = 0; i < values.size(); ++i) {
    pointers[i] = values[i] ? values[i]->c_str() : nullptr;
  }
  pg_result* raw = PQexecParams(conn_, sql, static_cast<int>(values.size()), nullptr,
                                pointers.data(), nullptr, nullptr, 0);
  Result owned(raw);
  Check(raw);
  return owned;
}

void Connection::ExecScript(const char* sql) {
  pg_result* raw = PQexec(conn_, sql);
  Result owned(raw);
  Check(raw);
}

void Connection::Check(pg_result* raw) const {
  // A null result only comes from a lost connection or no memory.
  const ExecStatusType status = raw != nullptr ? PQresultStatus(raw) : PGRES_FATAL_ERROR;
  if (status == PGRES_COMMAND_OK || status == PGRES_TUPLES_OK) return;
  if (!healthy()) {
    throw StorageError(Code::kUnavailable,
                       "postgresql: connection lost: " + FirstLine(PQerrorMessage(conn_)));
  }
  const char* state = raw != nullptr ? PQresultErrorField(raw, PG_DIAG_SQLSTATE) : nullptr;
  const std::string message =
      FirstLine(raw != nullptr ? PQresultErrorMessage(raw) : PQerrorMessage(conn_));
  throw StorageError(CodeOfSqlState(state != nullptr ? state : ""), "postgresql: " + message);
}

std::string DescribeServer(const std::string& conninfo) {
  PQconninfoOption* options = PQconninfoParse(conninfo.c_str(), nullptr);
  if (options == nullptr) return "(unparsable connection string)";
  std::string host, port, db;
  for (PQconninfoOption* o = options; o->keyword != nullptr; ++o) {
    if (o->val == nullptr) continue;
    if (std::strcmp(o->keyword, "host") == 0) host = o->val;
    if (std::strcmp(o->keyword, "port") == 0) port = o->val;
    if (std::strcmp(o->keyword, "dbname") == 0) db = o->val;
  }
  PQconninfoFree(options);
  return (host.empty() ? "localhost" : host) + (port.empty() ? "" : ":" + port) + "/" + db;
}

// ---- Transactions ----

Transaction::Transaction(Connection& conn, Kind kind) : conn_(conn) {
  conn_.ExecScript(kind == Kind::kRead ? "BEGIN ISOLATION LEVEL REPEATABLE READ READ ONLY"
                                       : "BEGIN ISOLATION LEVEL READ COMMITTED");
}

Transaction::~Transaction() {
  if (done_ || !conn_.healthy()) return;
  try {
    conn_.ExecScript("ROLLBACK");
  } catch (...) {  // a destructor must not throw; the pool drops a broken connection
  }
}

void Transaction::Commit() {
  conn_.ExecScript("COMMIT");
  done_ = true;
}

// ---- Schema ----

void MigrateSchema(Connection& conn, const std::vector<const char*>& steps) {
  constexpr int64_t kMigrationLock = 0x464D4150;  // "FMAP": one migrator among the replicas
  Transaction transaction(conn, Transaction::Kind::kWrite);
  conn.Exec("SELECT pg_advisory_xact_lock($1)", Params().Int64(kMigrationLock));
  conn.ExecScript(
      "CREATE TABLE IF NOT EXISTS forestmap_schema (version BIGINT NOT NULL); "
      "INSERT INTO forestmap_schema SELECT 0 WHERE NOT EXISTS (SELECT 1 FROM forestmap_schema)");
  const int64_t current = conn.Exec("SELECT version FROM forestmap_schema").Int64(0, 0);
  const auto target = static_cast<int64_t>(steps.size());
  if (current > target) {
    throw StorageError(Code::kInvalidArgument,
                       "postgresql: the database has schema version " + std::to_string(current) +
                           ", newer than this build's " + std::to_string(target) +
                           "; use a newer forestmapd");
  }
  for (int64_t version = current; version < target; ++version) {
    conn.ExecScript(steps[static_cast<size_t>(version)]);
    conn.Exec("UPDATE forestmap_schema SET version = $1", Params().Int64(version + 1));
  }
  transaction.Commit();
}

}  // namespace forestmap::storage::pg
