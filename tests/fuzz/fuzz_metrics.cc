// libFuzzer target for the metrics page (server/ops/metrics.h): the input, split at zero bytes,
// is a list of method names and label values from outside. Each becomes an RPC started and
// finished (its first byte picks the status code and whether it streams) and the label of a
// sampled series with a value read from the input (NaN and infinities included). The rendered
// page must stay well-formed text exposition: every line "# HELP name text", "# TYPE name type"
// or "name value" / "name{label="value",...} value" with the label values escaped, names
// valid, values numbers; and bounded: no label value longer than its cut, at most kMaxRpcSeries
// + 1 rpc labels, whatever was sent.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "server/ops/metrics.h"

namespace {

namespace fs = forestmap::server;

void Check(bool ok) {
  if (!ok) __builtin_trap();
}

bool IsNameChar(char c, bool first) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_' || c == ':' ||
         (!first && c >= '0' && c <= '9');
}

// A metric or label name: [a-zA-Z_:][a-zA-Z0-9_:]* (labels: no ':', not checked apart).
size_t NameLength(std::string_view text) {
  size_t n = 0;
  while (n < text.size() && IsNameChar(text[n], n == 0)) ++n;
  return n;
}

// A value as Prometheus reads it (Go's ParseFloat): a number, "+Inf", "-Inf" or "NaN".
void CheckValue(std::string_view value) {
  Check(!value.empty());
  if (value == "+Inf" || value == "-Inf" || value == "NaN") return;
  const std::string text(value);
  char* end = nullptr;
  std::strtod(text.c_str(), &end);
  Check(end == text.c_str() + text.size());
  for (const char c : value)
    Check((c >= '0' && c <= '9') || c == '.' || c == 'e' || c == '-' || c == '+');
}

// `{name="value",...}` at the start of `text`; returns its length. Collects the unescaped
// length of each value is at most the cut; the rpc values go into `rpcs`.
size_t CheckLabels(std::string_view text, std::set<std::string>& rpcs) {
  Check(text.starts_with('{'));
  size_t at = 1;
  for (;;) {
    const size_t name = NameLength(text.substr(at));
    Check(name > 0);
    const std::string_view label = text.substr(at, name);
    at += name;
    Check(text.substr(at).starts_with("=\""));
    at += 2;
    std::string value;
    for (;; ++at) {
      Check(at < text.size());
      const char c = text[at];
      if (c == '"') break;
      Check(c != '\n');
      if (c == '\\') {
        Check(at + 1 < text.size());
        const char escaped = text[++at];
        Check(escaped == '\\' || escaped == '"' || escaped == 'n');
        value += escaped == 'n' ? '\n' : escaped;
      } else {
        Check(c >= ' ' && c <= '~');  // printable ASCII: no stray byte
        value += c;
      }
    }
    ++at;  // the closing quote
    Check(value.size() <= fs::kMaxMetricLabelBytes);
    if (label == "rpc") rpcs.insert(value);
    if (at < text.size() && text[at] == ',') {
      ++at;
      continue;
    }
    Check(at < text.size() && text[at] == '}');
    return at + 1;
  }
}

void CheckPage(const std::string& page) {
  Check(page.empty() || page.back() == '\n');
  std::set<std::string> rpcs;
  size_t start = 0;
  while (start < page.size()) {
    const size_t end = page.find('\n', start);
    const std::string_view line(page.data() + start, end - start);
    start = end + 1;
    if (line.starts_with("# HELP ") || line.starts_with("# TYPE ")) {
      const std::string_view rest = line.substr(7);
      const size_t name = NameLength(rest);
      Check(name > 0 && name < rest.size() && rest[name] == ' ');
      if (line.starts_with("# TYPE ")) {
        const std::string_view type = rest.substr(name + 1);
        Check(type == "counter" || type == "gauge" || type == "histogram");
      }
      continue;
    }
    const size_t name = NameLength(line);
    Check(name > 0);
    size_t at = name;
    if (at < line.size() && line[at] == '{') at += CheckLabels(line.substr(at), rpcs);
    Check(at < line.size() && line[at] == ' ');
    CheckValue(line.substr(at + 1));
  }
  Check(rpcs.size() <= fs::kMaxRpcSeries + 1);
}

double ValueOf(std::string_view part) {
  if (part.size() < sizeof(double)) return static_cast<double>(part.size());
  double value = 0;
  std::memcpy(&value, part.data(), sizeof value);
  return value;  // any bits: NaN, infinities, subnormals
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  std::vector<std::string_view> parts;
  for (size_t at = 0; at <= input.size();) {
    const size_t end = std::min(input.find('\0', at), input.size());
    parts.push_back(input.substr(at, end - at));
    at = end + 1;
  }
  fs::Metrics metrics;
  for (const std::string_view part : parts) {
    const uint8_t first = part.empty() ? 0 : static_cast<uint8_t>(part[0]);
    const bool streaming = (first & 1) != 0;
    metrics.RpcStarted(part, streaming);
    if ((first & 2) == 0) {
      const auto code = static_cast<grpc::StatusCode>((first >> 2) % 17);
      metrics.RpcFinished(part, streaming, code, std::fabs(ValueOf(part)));
    }
  }
  metrics.AddGaugeSeries("forestmap_fuzz_series", "Label values from the input.", [&parts] {
    std::vector<fs::Metrics::Series> series;
    for (const std::string_view part : parts) {
      series.push_back(
          {"value=\"" + fs::MetricLabelValue(part) + "\",kind=\"fuzz\"", ValueOf(part)});
    }
    return series;
  });
  metrics.AddCounter("forestmap_fuzz_total", "One value.", [&parts] { return ValueOf(parts[0]); });
  CheckPage(metrics.Render());
  return 0;
}
