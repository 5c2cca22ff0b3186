#pragma once
// forestmapd's log: one line per event on stderr through spdlog, as text or as JSON lines, with
// time (UTC, ms), level and named fields. Every RPC gets one line when it ends (server/
// rpc_observer.h): rpc, request id, map, status code, duration; levels: OK -> info, client errors
// -> warn, server faults (INTERNAL, UNKNOWN, DATA_LOSS) -> error, health checks -> debug.
//
//   text: 2026-11-26T08:01:02.345Z info rpc rpc=GetMap request_id=5f0c... map=plot-7 code=OK
//   ms=0.41 json: {"time":"2026-11-26T08:01:02.345Z","level":"info","msg":"rpc","rpc":"GetMap",...}
//
// Thread-safety: everything may be called from any thread; ConfigureLogging before serving.

#include <string>
#include <string_view>
#include <vector>

namespace forestmap::server {

enum class LogLevel { kDebug, kInfo, kWarn, kError };
enum class LogFormat { kText, kJson };

struct LogOptions {
  LogFormat format = LogFormat::kText;  // --log-format text|json
  LogLevel level = LogLevel::kInfo;     // --log-level: lines below it are dropped
};

// "debug", "info", "warn", "error" / "text", "json"; throw std::invalid_argument otherwise.
LogLevel ParseLogLevel(std::string_view name);
LogFormat ParseLogFormat(std::string_view name);

// Replaces the process-wide logger (stderr). Without a call: text, info.
void ConfigureLogging(const LogOptions& options);

// Changes the level of the running logger (forestmapd's SIGHUP) and returns the one it replaced.
LogLevel SetLogLevel(LogLevel level);
const char* LogLevelName(LogLevel level);  // "debug", "info", "warn", "error"

// Sends gRPC's own log lines (gpr_log: errors unless GRPC_VERBOSITY says otherwise) through
// Log, with the field source=grpc, in the format of the others. Until GrpcErrorsAreWarnings(),
// gRPC's errors are debug lines kept for HeldGrpcErrors(): a start-up failure is then one line,
// forestmapd's own, naming the flag, with gRPC's reason as a field ("Name or service not known"
// alone says neither the flag nor the address). Its failed assertions are errors always (the
// process aborts). After it, gRPC's errors are warnings.
void RouteGrpcLogs();
void GrpcErrorsAreWarnings();
std::string HeldGrpcErrors();  // "; "-joined; empty when none

struct LogField {
  std::string_view key;
  std::string value;
  bool number = false;  // JSON: written unquoted (the value must then be a valid number)
};

// One log line: `message` and its fields. Never throws.
void Log(LogLevel level, std::string_view message,
         const std::vector<LogField>& fields = {}) noexcept;

// JSON string escaping of `text` (without the quotes); invalid UTF-8 bytes become \u00XX.
std::string JsonEscape(std::string_view text);

}  // namespace forestmap::server
