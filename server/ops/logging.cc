#include "server/ops/logging.h"

#include <grpc/support/log.h>
#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>

#include <atomic>
#include <cstdio>
#include <memory>
#include <mutex>
#include <stdexcept>

namespace forestmap::server {
namespace {

// Read by Log() on every call; swapped by ConfigureLogging (before serving).
std::atomic<LogFormat> g_format{LogFormat::kText};
std::atomic<LogLevel> g_level{LogLevel::kInfo};
std::atomic<bool> g_grpc_errors_are_warnings{false};
std::mutex g_held_mutex;
std::string g_held_grpc_errors;  // guarded by g_held_mutex
std::once_flag g_default_once;
std::atomic<bool> g_configured{false};

spdlog::level::level_enum ToSpdlog(LogLevel level) {
  switch (level) {
    case LogLevel::kDebug:
      return spdlog::level::debug;
    case LogLevel::kInfo:
      return spdlog::level::info;
    case LogLevel::kWarn:
      return spdlog::level::warn;
    case LogLevel::kError:
      return spdlog::level::err;
  }
  return spdlog::level::info;
}

// A text value needs quotes when it is empty or holds a space, a quote or '='.
std::string TextValue(const std::string& value) {
  if (!value.empty() && value.find_first_of(" \"=\t\n") == std::string::npos) return value;
  std::string quoted = "\"";
  quoted.append(JsonEscape(value)).append("\"");
  return quoted;
}

std::string Format(LogFormat format, std::string_view message,
                   const std::vector<LogField>& fields) {
  std::string line;
  if (format == LogFormat::kJson) {
    line.append("\"msg\":\"").append(JsonEscape(message)).append("\"");
    for (const LogField& field : fields) {
      line.append(",\"").append(JsonEscape(field.key)).append("\":");
      if (field.number) {
        line.append(field.value);
      } else {
        line.append("\"").append(JsonEscape(field.value)).append("\"");
      }
    }
    return line;
  }
  line = message;
  for (const LogField& field : fields) {
    line.append(" ").append(field.key).append("=").append(TextValue(field.value));
  }
  return line;
}

// Without ConfigureLogging (tests): text on stderr, not spdlog's default (stdout).
void EnsureLogger() {
  std::call_once(g_default_once, [] {
    if (!g_configured) ConfigureLogging({});
  });
}

}  // namespace

LogLevel ParseLogLevel(std::string_view name) {
  if (name == "debug") return LogLevel::kDebug;
  if (name == "info") return LogLevel::kInfo;
  if (name == "warn") return LogLevel::kWarn;
  if (name == "error") return LogLevel::kError;
  throw std::invalid_argument("log level must be debug, info, warn or error, not '" +
                              std::string(name) + "'");
}

LogFormat ParseLogFormat(std::string_view name) {
  if (name == "text") return LogFormat::kText;
  if (name == "json") return LogFormat::kJson;
  throw std::invalid_argument("log format must be text or json, not '" + std::string(name) + "'");
}

void ConfigureLogging(const LogOptions& options) {
  auto logger = std::make_shared<spdlog::logger>("forestmapd",
                                                 std::make_shared<spdlog::sinks::stderr_sink_mt>());
  // The message of a JSON line is already a list of fields: the pattern closes the object.
  logger->set_pattern(options.format == LogFormat::kJson
                          ? R"({"time":"%Y-%m-%dT%H:%M:%S.%eZ","level":"%l",%v})"
                          : "%Y-%m-%dT%H:%M:%S.%eZ %l %v",
                      spdlog::pattern_time_type::utc);
  logger->set_level(ToSpdlog(options.level));
  logger->flush_on(spdlog::level::debug);  // one line per event, never held back
  g_format = options.format;
  g_level = options.level;
  spdlog::set_default_logger(std::move(logger));
  g_configured = true;
}

LogLevel SetLogLevel(LogLevel level) {
  EnsureLogger();
  spdlog::default_logger()->set_level(ToSpdlog(level));
  return g_level.exchange(level);
}

const char* LogLevelName(LogLevel level) {
  switch (level) {
    case LogLevel::kDebug:
      return "debug";
    case LogLevel::kInfo:
      return "info";
    case LogLevel::kWarn:
      return "warn";
    case LogLevel::kError:
      return "error";
  }
  return "info";
}

void RouteGrpcLogs() {
  gpr_set_log_function([](gpr_log_func_args* args) {
    const std::string_view message = args->message;
    LogLevel level = LogLevel::kDebug;
    if (args->severity == GPR_LOG_SEVERITY_ERROR) {
      if (g_grpc_errors_are_warnings) {
        level = LogLevel::kWarn;
      } else if (message.starts_with("assertion failed")) {
        level = LogLevel::kError;
      } else {
        const std::lock_guard lock(g_held_mutex);
        if (!g_held_grpc_errors.empty()) g_held_grpc_errors += "; ";
        g_held_grpc_errors += message.substr(0, message.find(" {"));  // without gRPC's details
      }
    }
    Log(level, message,
        {{"source", "grpc"}, {"at", std::string(args->file) + ":" + std::to_string(args->line)}});
  });
}

std::string HeldGrpcErrors() {
  const std::lock_guard lock(g_held_mutex);
  return g_held_grpc_errors;
}

void GrpcErrorsAreWarnings() { g_grpc_errors_are_warnings = true; }

void Log(LogLevel level, std::string_view message, const std::vector<LogField>& fields) noexcept {
  try {
    EnsureLogger();
    if (!spdlog::should_log(ToSpdlog(level))) return;
    spdlog::log(ToSpdlog(level), "{}", Format(g_format, message, fields));
  } catch (...) {
    std::fputs("forestmapd: logging failed\n", stderr);
  }
}

std::string JsonEscape(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (byte < 0x20 || byte >= 0x80) {
      // Control characters, and non-ASCII bytes (which may not be valid UTF-8): \u00XX.
      char escaped[8];
      std::snprintf(escaped, sizeof escaped, "\\u%04x", byte);
      out += escaped;
    } else {
      out += c;
    }
  }
  return out;
}

}  // namespace forestmap::server
